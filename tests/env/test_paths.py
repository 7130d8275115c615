"""Path model, path files (loader validation), the paper's square and the random generator."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flagellum_env.paths import (
    PAPER_SQUARE_SIDE_M,
    RandomPathConfig,
    WaypointPath,
    load_path,
    path_from_waypoints,
    random_path,
    save_path,
    square_path,
)


def _write(tmp_path, data, name="p.json"):
    f = tmp_path / name
    f.write_text(data if isinstance(data, str) else json.dumps(data))
    return f


def test_square_is_the_papers_closed_square_of_side_quarter_metre():
    p = square_path()
    assert p.n_waypoints == 4
    assert np.allclose(p.segment_lengths, PAPER_SQUARE_SIDE_M)
    assert p.length_m == pytest.approx(4 * 0.25)
    assert np.array_equal(p.waypoints[-1], [0.0, 0.0, 0.0])  # back at the start
    assert np.all(p.waypoints[:, 2] == 0.0)
    assert p.waypoints[0, 0] > 0  # first leg straight ahead (+x)


def test_path_file_round_trips(tmp_path):
    p = path_from_waypoints([[0.01, 0, 0], [0.02, 0.01, -0.005]], name="zz", reach_radius_m=0.004)
    f = tmp_path / "zz.json"
    save_path(p, f)
    assert load_path(f) == p


def test_path_file_name_defaults_to_file_stem_and_radius_is_optional(tmp_path):
    p = load_path(_write(tmp_path, {"waypoints": [[0.01, 0, 0]]}, "my_path.json"))
    assert p.name == "my_path"
    assert p.reach_radius_m is None


@pytest.mark.parametrize("data, match", [
    ("{not json", "not valid JSON"),
    ([[0.01, 0, 0]], "JSON object"),
    ({"name": "x"}, "missing 'waypoints'"),
    ({"waypoints": []}, "at least one"),
    ({"waypoints": [[0.01, 0]]}, r"waypoint 0 .* must be \[x, y, z\]"),
    ({"waypoints": [[0.01, 0, 0], [0.02, "a", 0]]}, "waypoint 1 .* non-numeric"),
    ({"waypoints": [[0.01, 0, 0], [0.02, True, 0]]}, "waypoint 1 .* non-numeric"),
    ('{"waypoints": [[0.01, 0, NaN]]}', "non-finite"),
    ('{"waypoints": [[0.01, 0, Infinity]]}', "non-finite"),
    ({"waypoints": [[0.01, 0, 0], [0.01, 0, 0]]}, "zero-length segment from waypoint 0 to waypoint 1"),
    ({"waypoints": [[0.0, 0, 0], [0.01, 0, 0]]}, "zero-length segment from the start"),
    ({"waypoints": [[0.01, 0, 0]], "reach_radius_m": -1}, "reach_radius_m"),
    ({"waypoints": [[0.01, 0, 0]], "reach_radius_m": "big"}, "reach_radius_m"),
    ({"waypoints": [[0.01, 0, 0]], "name": 3}, "'name' must be a non-empty string"),
    ({"waypoints": [[0.01, 0, 0]], "wayponts": []}, r"unknown key\(s\) \['wayponts'\]"),
])
def test_bad_path_files_raise_clear_errors(tmp_path, data, match):
    f = _write(tmp_path, data)
    with pytest.raises(ValueError, match=match) as exc:
        load_path(f)
    if match != "JSON object":
        assert str(f) in str(exc.value)  # the message names the file


def test_missing_path_file_names_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.json"):
        load_path(tmp_path / "nope.json")


def test_waypoints_are_read_only_copies():
    pts = np.array([[0.01, 0.0, 0.0]])
    p = WaypointPath("a", pts)
    pts[0, 0] = 5.0
    assert p.waypoints[0, 0] == 0.01
    with pytest.raises(ValueError):
        p.waypoints[0, 0] = 1.0


def test_random_path_is_determined_by_the_generator_state():
    a = random_path(np.random.default_rng(7))
    b = random_path(np.random.default_rng(7))
    c = random_path(np.random.default_rng(8))
    assert a == b
    assert a != c


@pytest.mark.parametrize("planar", [True, False])
def test_random_path_respects_lengths_turns_and_plane(planar):
    cfg = RandomPathConfig(n_waypoints=6, segment_length_m=(0.02, 0.05), max_turn_deg=45.0, planar=planar)
    for seed in range(5):
        p = random_path(np.random.default_rng(seed), cfg)
        assert p.n_waypoints == 6
        lengths = p.segment_lengths
        assert np.all(lengths >= 0.02 - 1e-12) and np.all(lengths <= 0.05 + 1e-12)
        d = np.diff(p.vertices, axis=0)
        headings = np.vstack([[1.0, 0.0, 0.0], d / lengths[:, None]])
        turns = np.degrees(np.arccos(np.clip(np.sum(headings[1:] * headings[:-1], axis=1), -1, 1)))
        assert np.all(turns <= 45.0 + 1e-6)
        if planar:
            assert np.all(p.waypoints[:, 2] == 0.0)
    if not planar:
        assert np.any(np.abs(p.waypoints[:, 2]) > 1e-4)


@pytest.mark.parametrize("kwargs, match", [
    ({"n_waypoints": 0}, "n_waypoints"),
    ({"n_waypoints": 2.5}, "n_waypoints"),
    ({"segment_length_m": (0.05, 0.01)}, "segment_length_m"),
    ({"segment_length_m": (0.0, 0.01)}, "segment_length_m"),
    ({"segment_length_m": 0.01}, "segment_length_m"),
    ({"max_turn_deg": 200}, "max_turn_deg"),
    ({"planar": "yes"}, "planar"),
    ({"n_waypoints": (3, 2)}, r"n_waypoints=\(3, 2\)"),
    ({"n_waypoints": (0, 2)}, "n_waypoints"),
    ({"n_waypoints": (1.5, 2)}, "n_waypoints"),
    ({"reach_radius_m": (0.03, 0.01)}, "reach_radius_m"),
    ({"reach_radius_m": 0.01}, "reach_radius_m"),
])
def test_random_path_config_rejects_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        RandomPathConfig(**kwargs)


@pytest.mark.parametrize("waypoints", [[[1e308, 0.0, 0.0]], [[0.01, 0.0, 0.0], [0.01, -1e6, 0.0]]])
def test_waypoints_out_of_reach_are_refused_by_every_loader(tmp_path, waypoints):
    """Issue 24: 1e308 overflowed the path length (OverflowError in `follow`), 1e6 m was accepted silently."""
    with pytest.raises(ValueError, match=r"out of reach; allowed: coordinates within \+-100 m"):
        path_from_waypoints(waypoints)
    f = tmp_path / "far.json"
    f.write_text(json.dumps({"waypoints": waypoints}))
    with pytest.raises(ValueError, match=r"far.json: waypoint .* out of reach"):
        load_path(f)


def test_ranges_of_corners_and_reach_radius_are_drawn_within_them():
    cfg = RandomPathConfig(n_waypoints=(2, 5), segment_length_m=(0.05, 0.4), min_turn_deg=20.0, max_turn_deg=175.0,
                           reach_radius_m=(0.01, 0.03))
    drawn = [random_path(np.random.default_rng(s), cfg) for s in range(40)]
    assert {p.n_waypoints for p in drawn} == {2, 3, 4, 5}
    assert all(0.01 <= p.reach_radius_m <= 0.03 for p in drawn)
    assert random_path(np.random.default_rng(3), cfg) == drawn[3]


def test_a_config_without_ranges_draws_the_committed_eval_paths():
    """The held-out paths (scripts/make_eval_paths.py) come out of the generator as they were committed."""
    import importlib.util
    from pathlib import Path

    from agents.assets import eval_paths_dir
    from flagellum_env.paths import load_path

    spec = importlib.util.spec_from_file_location(
        "make_eval_paths", Path(__file__).resolve().parents[2] / "scripts" / "make_eval_paths.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    for kind, planar in (("planar", True), ("3d", False)):
        cfg = RandomPathConfig(**{**mod.EVAL_PATHS.__dict__, "planar": planar})
        for seed in (1000, 1007):
            p = random_path(np.random.default_rng(seed), cfg)
            committed = load_path(eval_paths_dir() / f"{kind}_{seed}.json")
            # the same draws (the files were written by an older, ULP-different rotation: 6e-17 m)
            assert np.allclose(p.waypoints, committed.waypoints, rtol=0.0, atol=1e-12) and p.reach_radius_m is None
