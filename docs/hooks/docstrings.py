"""MkDocs hook: ``<!-- docstring: icv_envs/envs/highway_formation_v0.py -->``
in a page is replaced by that module's docstring (read with ``ast``, nothing
is imported), so the env pages and the module docstrings are one text.
``<!-- docstring: PATH rst -->`` also turns reST definition lists (a term
line followed by a block indented 4 spaces) into Markdown ones.

Sphinx roles (``:class:`~a.b.C```) become code spans (`` `C` ``); the
docstring's first heading is dropped (the page has its own title).
A marker naming a missing file or a file without a docstring is an error,
which ``mkdocs build --strict`` reports.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MARKER = re.compile(r"<!--\s*docstring:\s*(\S+?)(\s+rst)?\s*-->")
ROLE = re.compile(r":(?:class|func|meth|mod|data|attr|obj|exc):`~?([^`]+)`")


def _definition_lists(lines: list[str]) -> list[str]:
    out = []
    for k, line in enumerate(lines):
        prev = lines[k - 1] if k else ""
        if (line.startswith("    ") and not line.startswith("     ") and prev.strip()
                and not prev.startswith(" ")):
            out.append(":   " + line[4:])
        else:
            out.append(line)
    return out


def _docstring(rel: str, rst: bool = False) -> str:
    path = ROOT / rel
    if not path.is_file():
        raise FileNotFoundError(f"docstring marker names {rel!r}, which does not exist")
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
    if not doc:
        raise ValueError(f"{rel!r} has no module docstring")
    doc = ROLE.sub(lambda m: f"`{m.group(1)}`", doc)
    doc = doc.replace("``", "`")
    lines = doc.strip().splitlines()
    if lines and lines[0].startswith("# "):
        lines = lines[1:]
    if rst:
        lines = _definition_lists(lines)
    return "\n".join(lines).strip() + "\n"


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001 (MkDocs hook signature)
    return MARKER.sub(lambda m: _docstring(m.group(1), bool(m.group(2))), markdown)
