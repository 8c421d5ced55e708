"""Frames a person understands: every frame carries the env and scenario (or
method and demand), the simulated time and a legend; the intersection frame
shows the scene out to R3 with every vehicle visible, plus a true-size inset
of the box. Frames are real pixels (not black) and the overlay can be
switched off."""

import numpy as np
import pytest

from icv_envs import highway_formation_v0, highway_ramps_v0, intersection_v0
from icv_envs.envs.intersection import IntersectionEnv


def _frame(mod, steps, **config):
    env = mod.parallel_env(render_mode="rgb_array", **config)
    env.reset(seed=0)
    for _ in range(steps):
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    img = env.render()
    title = env.core.viewer.title_lines()
    legend = [item[0] for item in env.core.viewer.legend_items()]
    env.close()
    return img, title, legend


def _dark_panel(img, y0, y1, x0, x1):
    """Share of pixels in the box that are the overlay's dark translucent panel."""
    box = img[y0:y1, x0:x1].astype(int)
    return float((box.max(axis=-1) < 60).mean())


def test_highway_frame_has_title_time_and_legend():
    img, title, legend = _frame(highway_formation_v0, 50, scenario="lane-drop")
    assert img.std() > 10 and img.max() == 255  # a drawn frame, not black or blank
    assert "HighwayFormation-v0" in title[0] and "lane-drop" in title[0]
    assert title[1].startswith("t =   10.0 s") and "8 vehicles" in title[1]
    assert any("formation" in s for s in legend) and "target" in legend and "crashed" in legend
    plain, _, _ = _frame(highway_formation_v0, 50, scenario="lane-drop", show_overlay=False)
    diff = np.any(img != plain, axis=-1)
    h, w = diff.shape
    assert diff[:50, :300].mean() > 0.3  # the title panel (top left)
    assert diff[h - 30:, :600].mean() > 0.3  # the legend (bottom)
    assert not diff[60:h - 40, 400:].any()  # the road in between is untouched
    assert _dark_panel(img, 8, 40, 8, 200) > 0.4 and _dark_panel(plain, 8, 40, 8, 200) == 0.0


def test_the_time_stamp_advances():
    a, ta, _ = _frame(highway_formation_v0, 5, scenario="free", duration=5.0)
    b, tb, _ = _frame(highway_formation_v0, 10, scenario="free", duration=5.0)
    assert ta[1].startswith("t =    1.0 s") and tb[1].startswith("t =    2.0 s")
    assert np.any(a[:50, :300] != b[:50, :300])


def test_ramps_frame_names_method_and_vgr():
    img, title, _ = _frame(highway_ramps_v0, 25, method="lane-lp", vgr=0.2, duration=10.0)
    assert img.std() > 10
    assert "HighwayRamps-v0" in title[0] and "lane-lp" in title[0] and "VGR 0.2" in title[0]


def test_intersection_frame_shows_r3_and_visible_vehicles():
    img, title, legend = _frame(intersection_v0, 400, throughput=2000.0, duration=100.0)
    assert img.shape == (900, 900, 3) and img.std() > 10
    assert "multi-vp" in title[0] and "2000 veh/h" in title[0] and "lane use paper" in title[0]
    assert title[1].startswith("t =   80.0 s")
    assert {"R1 coordinating", "R2 adjusting", "R3 arrivals"} <= set(legend)
    # the R3 circle (800 m) is inside the frame: its colour on the far left and right of the centre row band
    r3 = np.all(img == np.array((230, 230, 230), dtype=np.uint8), axis=-1)
    cols = np.flatnonzero(r3[440:460].any(axis=0))
    assert cols.size and cols.min() < 60 and cols.max() > 840
    plain, _, _ = _frame(intersection_v0, 400, throughput=2000.0, duration=100.0, show_overlay=False)
    # vehicles are markers of at least 7 x 4 px even at 0.54 px/m: count vehicle-coloured pixels
    # outside the inset/title/legend areas, on the plain frame
    grey = np.all(plain == np.array((200, 200, 200), dtype=np.uint8), axis=-1)
    blue = np.all(plain == np.array((150, 200, 255), dtype=np.uint8), axis=-1)
    layer = np.zeros_like(grey)
    for c in IntersectionEnv.LAYER_COLOURS:
        layer |= np.all(plain == np.array(c, dtype=np.uint8), axis=-1)
    assert (grey | blue | layer).sum() > 20 * 15  # more than 20 vehicles of >= 15 px each
    # the inset (bottom right) is drawn only with the overlay; it shows the box at true size
    diff = np.any(img != plain, axis=-1)
    assert diff[600:894, 600:894].mean() > 0.2  # (grass is grass in both)
    road = lambda f: np.all(f[600:894, 600:894] == np.array((100, 100, 100), dtype=np.uint8), axis=-1).mean()
    assert road(img) > 0.2 and road(plain) < 0.05  # the zoomed box and legs (12 m wide legs: 2.5 px/m)


def test_intersection_background_is_cached_and_zones_switch_off():
    env = intersection_v0.parallel_env(render_mode="rgb_array", duration=5.0)
    env.reset(seed=0)
    env.render()
    viewer = env.core.viewer
    cache = dict(viewer._bg_cache)
    env.step({a: [0.0, 0.0] for a in env.agents})
    env.render()
    assert {k: id(v[1]) for k, v in viewer._bg_cache.items()} == {k: id(v[1]) for k, v in cache.items()}
    env.close()
    on, _, _ = _frame(intersection_v0, 1, duration=5.0, show_overlay=False)
    off, _, legend = _frame(intersection_v0, 1, duration=5.0, show_overlay=False, show_zones=False)
    r3 = lambda f: int(np.all(f == np.array((230, 230, 230), dtype=np.uint8), axis=-1).sum())
    assert r3(on) > 500 and r3(off) == 0 and "R3 arrivals" not in legend


@pytest.mark.parametrize("mod", [highway_formation_v0, intersection_v0])
def test_fcfs_and_gym_ego_legends(mod):
    if mod is intersection_v0:
        _, _, legend = _frame(mod, 1, method="fcfs", duration=5.0)
        assert "holds a reservation" in legend
    import gymnasium as gym

    gid = "icv_envs/HighwayFormation-v0" if mod is highway_formation_v0 else "icv_envs/Intersection-v0"
    env = gym.make(gid, render_mode="rgb_array", config={"duration": 5.0})
    env.reset(seed=0)
    img = env.render()
    assert img.std() > 10 and "learned ego" in [i[0] for i in env.unwrapped.viewer.legend_items()]
    env.close()


@pytest.mark.parametrize("mod", [highway_formation_v0, highway_ramps_v0, intersection_v0])
def test_show_overlay_must_be_a_bool(mod):
    with pytest.raises(ValueError, match=r"show_overlay.*True or False"):
        mod.parallel_env(show_overlay="yes")


def test_env_pickles_after_render_and_draws_the_same_frame():
    import pickle

    env = intersection_v0.parallel_env(render_mode="rgb_array", duration=20.0, throughput=2000.0)
    env.reset(seed=0)
    for _ in range(20):
        ex = env.expert_actions()
        env.step({a: ex[a] for a in env.agents})
    frame = env.render()
    clone = pickle.loads(pickle.dumps(env))
    np.testing.assert_array_equal(clone.render(), frame)
    env.close()
    clone.close()
