"""The documentation in docs/ builds with ``mkdocs build --strict`` (broken
links and anchors are errors), every ``docs/<page>.md#anchor`` cited from the
code, tests, notebooks and README exists, and nothing points to reading notes
that are not in the repository."""

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
CITED = re.compile(r"docs/([\w/.-]+\.md)(?:#([\w-]+))?")
SOURCES = [ROOT / "README.md", *sorted((ROOT / "icv_envs").rglob("*.py")), *sorted((ROOT / "tests").glob("*.py")),
           *sorted((ROOT / "notebooks").glob("*.ipynb")), *sorted((ROOT / "baselines").glob("*.py")),
           *sorted((ROOT / "scripts").glob("*.py"))]


def _mkdocs_available() -> bool:
    try:
        import mkdocs  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.skipif(not _mkdocs_available(), reason="mkdocs is not installed (pip install -e '.[test]')")
def test_mkdocs_build_strict(tmp_path):
    exe = shutil.which("mkdocs")
    cmd = [exe] if exe else [sys.executable, "-m", "mkdocs"]
    p = subprocess.run([*cmd, "build", "--strict", "--site-dir", str(tmp_path / "site")], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout + p.stderr
    site = tmp_path / "site"
    assert (site / "index.html").is_file()
    for page in ("model", "formation", "intersection", "methods", "metrics", "decisions", "rendering",
                 "cli", "spaces", "envs/highway_formation", "envs/highway_ramps", "envs/intersection"):
        assert (site / page / "index.html").is_file(), page
    # the env pages include their module docstrings (one text, not a copy)
    html = (site / "envs" / "intersection" / "index.html").read_text()
    assert "envelope_box_binding" in html and "docstring:" not in html
    assert "<dt><code>DiscreteMetaAction</code></dt>" in (site / "spaces" / "index.html").read_text()


def _anchors(md: Path) -> set[str]:
    from markdown.extensions.toc import slugify

    ids = set()
    text = md.read_text(encoding="utf-8")
    # pages that include module docstrings get their headings too
    for inc in re.findall(r"<!--\s*docstring:\s*(\S+?)\s*-->", text):
        import ast

        text += "\n" + (ast.get_docstring(ast.parse((ROOT / inc).read_text(encoding="utf-8"))) or "")
    for line in text.splitlines():
        m = re.match(r"^#{1,6}\s+(.*?)\s*(?:\{#([\w-]+)\})?\s*$", line)
        if m:
            ids.add(m.group(2) or slugify(m.group(1), "-"))
    return ids


def test_every_cited_docs_page_and_anchor_exists():
    bad = []
    for src in SOURCES:
        for n, line in enumerate(src.read_text(encoding="utf-8").splitlines(), 1):
            for page, anchor in CITED.findall(line):
                md = DOCS / page
                if not md.is_file():
                    bad.append(f"{src.relative_to(ROOT)}:{n}: docs/{page} does not exist")
                elif anchor and anchor not in _anchors(md):
                    bad.append(f"{src.relative_to(ROOT)}:{n}: docs/{page} has no anchor #{anchor}")
    assert not bad, "\n".join(bad)


def test_code_cites_the_docs():
    cited = {page for src in SOURCES for page, _ in CITED.findall(src.read_text(encoding="utf-8"))}
    assert {"formation.md", "intersection.md", "metrics.md", "methods.md"} <= cited


def test_no_reference_to_notes_outside_the_repository():
    name = "NOTES" + ".md"  # (spelled so this file does not match itself)
    hits = [f"{src.relative_to(ROOT)}" for src in [*SOURCES, *DOCS.rglob("*.md"), ROOT / "mkdocs.yml"]
            if name in src.read_text(encoding="utf-8") and src != Path(__file__).resolve()]
    assert not hits, f"{name} is not in the repository, but cited in {hits}"


def test_docs_show_the_corrected_target_table():
    """The table printed in docs/formation.md is what the code computes."""
    from icv_envs.formation.targets import interlaced_targets

    text = (DOCS / "formation.md").read_text(encoding="utf-8")
    x, lane = interlaced_targets(10, 5, 1.0)
    row = " ".join(f"({int(a)},{int(b)})" for a, b in zip(x, lane))
    assert f"corrected: {row}" in text
    for n_l in (3, 4):
        x, lane = interlaced_targets(2 * n_l, n_l, 1.0)
        assert " ".join(f"({int(a)},{int(b)})" for a, b in zip(x, lane)) in text


def test_readme_links_the_docs_and_shows_a_gif_of_each_env():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    lines = readme.splitlines()
    assert lines[0] == "pip install -e . && icv-envs demo --out demo_out"
    assert lines[1].startswith("pip install torch==2.13.0 && pip install -e")
    assert "docs/index.md" in readme
    for env in ("highway_formation", "highway_ramps", "intersection"):
        gif = ROOT / "docs" / "gifs" / f"{env}.gif"
        assert f"docs/gifs/{env}.gif" in readme and gif.is_file()
        assert 10_000 < gif.stat().st_size < 2_000_000


def test_package_metadata():
    import tomllib

    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert meta["license"] == {"text": "MIT"} and "MIT License" in (ROOT / "LICENSE").read_text()
    assert any(d.replace(" ", "").startswith("pettingzoo>=1.27") for d in meta["dependencies"])
    assert any(d.startswith("mkdocs") for d in meta["optional-dependencies"]["test"])
    assert meta["keywords"] and meta["urls"] and any("Typing :: Typed" in c for c in meta["classifiers"])
    assert (ROOT / "icv_envs" / "py.typed").is_file()
    cff = (ROOT / "CITATION.cff").read_text()
    assert "cff-version" in cff and "IET Intelligent Transport Systems" in cff and "Coordinated Formation" in cff
    assert "## [0.1.0]" in (ROOT / "CHANGELOG.md").read_text()
