"""MotorSchedule: construction rules, lookup, averaging and file loading with clear errors."""

from __future__ import annotations

import json
import math

import pytest

from physics.params import RPM_TO_RAD_S
from physics.schedule import MAX_RPM, MotorSchedule


def test_constant_schedule_gives_the_same_speed_at_every_time():
    s = MotorSchedule.constant(10.0)
    assert s.is_constant
    assert [s.omega_rpm_at(t) for t in (0.0, 1.0, 1e6)] == [10.0, 10.0, 10.0]
    assert s.omega_rad_s_at(3.0) == pytest.approx(10.0 * RPM_TO_RAD_S)


def test_steps_switch_exactly_at_their_start_time():
    s = MotorSchedule(((0.0, 10.0), (10.0, 60.0), (15.0, 0.0)))
    assert s.omega_rpm_at(0.0) == 10.0
    assert s.omega_rpm_at(9.999) == 10.0
    assert s.omega_rpm_at(10.0) == 60.0
    assert s.omega_rpm_at(14.9) == 60.0
    assert s.omega_rpm_at(100.0) == 0.0
    assert not s.is_constant


def test_mean_speed_is_the_time_average():
    s = MotorSchedule(((0.0, 10.0), (10.0, 60.0)))
    assert s.mean_omega_rpm(20.0) == pytest.approx(35.0)
    assert s.mean_omega_rpm(5.0) == pytest.approx(10.0)


def test_lists_are_normalised_to_a_hashable_tuple_of_floats():
    s = MotorSchedule([[0, 1], [2, 3]])
    assert s.steps == ((0.0, 1.0), (2.0, 3.0))
    assert hash(s) == hash(MotorSchedule(((0.0, 1.0), (2.0, 3.0))))
    assert s.to_list() == [[0.0, 1.0], [2.0, 3.0]]


@pytest.mark.parametrize("steps, fragment", [
    ((), "at least one step"),
    (((1.0, 10.0),), "first step must start at time_s=0"),
    (((0.0, 10.0), (0.0, 20.0)), "greater than the previous"),
    (((0.0, 10.0), (5.0, 20.0), (4.0, 1.0)), "time_s=4.0"),
    (((0.0, -1.0),), "omega_rpm=-1.0"),
    (((0.0, math.nan),), "omega_rpm=nan"),
    (((0.0, MAX_RPM + 1),), "<= 10000"),
    (((0.0, 1.0), (math.inf, 1.0)), "time_s=inf"),
])
def test_invalid_steps_are_rejected_with_the_bad_value(steps, fragment):
    with pytest.raises(ValueError) as info:
        MotorSchedule(steps)
    assert fragment in str(info.value)


@pytest.mark.parametrize("w", [-3.0, math.nan, math.inf, 1e5])
def test_constant_rejects_bad_speeds_and_names_them(w):
    with pytest.raises(ValueError) as info:
        MotorSchedule.constant(w)
    assert repr(w) in str(info.value) and "allowed" in str(info.value)


def test_load_csv_with_header_comments_and_blank_lines(tmp_path):
    f = tmp_path / "s.csv"
    f.write_text("# demo\ntime_s,omega_rpm\n0,10\n\n10, 60\n")
    assert MotorSchedule.load(f).steps == ((0.0, 10.0), (10.0, 60.0))


def test_load_csv_without_header(tmp_path):
    f = tmp_path / "s.csv"
    f.write_text("0,5\n2.5,7\n")
    assert MotorSchedule.load(f).steps == ((0.0, 5.0), (2.5, 7.0))


def test_load_json_list_and_object_forms(tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps([[0, 10], [1, 20]]))
    b.write_text(json.dumps({"steps": [[0, 10], [1, 20]]}))
    assert MotorSchedule.load(a) == MotorSchedule.load(b) == MotorSchedule(((0.0, 10.0), (1.0, 20.0)))


@pytest.mark.parametrize("text, fragments", [
    ("time_s,omega_rpm\n0,10\n5,fast\n", ["row 3", "omega_rpm='fast'", "not a number"]),
    ("0,10\n5,-2\n", ["row 2", "omega_rpm=-2.0", "allowed"]),
    ("0,10\n5,1,2\n", ["row 2", "2 columns"]),
    ("t,w\n0,1\n", ["row 1", "header"]),
    ("1,10\n", ["row 1", "time_s=0"]),
    ("0,10\n0,20\n", ["row 2", "greater than"]),
    ("# nothing\n", ["no schedule rows"]),
])
def test_bad_csv_errors_name_file_row_and_value(tmp_path, text, fragments):
    f = tmp_path / "bad.csv"
    f.write_text(text)
    with pytest.raises(ValueError) as info:
        MotorSchedule.load(f)
    msg = str(info.value)
    assert str(f) in msg
    for frag in fragments:
        assert frag in msg


@pytest.mark.parametrize("text, fragments", [
    ("[[0, 10], [1, \"x\"]]", ["entry[1]", "'x'", "not a number"]),
    ("{\"steps\": [[0, 10], [1]]}", ["steps[1]", "pair"]),
    ("{\"speeds\": []}", ["'steps'"]),
    ("[[0, 10], [1, NaN]]", ["entry[1]", "omega_rpm=nan"]),
    ("[[0, 10],", ["not valid JSON"]),
    ("[]", ["non-empty list"]),
])
def test_bad_json_errors_name_file_entry_and_value(tmp_path, text, fragments):
    f = tmp_path / "bad.json"
    f.write_text(text)
    with pytest.raises(ValueError) as info:
        MotorSchedule.load(f)
    msg = str(info.value)
    assert str(f) in msg
    for frag in fragments:
        assert frag in msg


def test_missing_file_is_a_value_error_naming_it(tmp_path):
    f = tmp_path / "missing.csv"
    with pytest.raises(ValueError, match="missing.csv"):
        MotorSchedule.load(f)


def test_demo_schedule_example_loads():
    from pathlib import Path

    demo = Path(__file__).resolve().parents[1] / "examples" / "demo_schedule.csv"
    assert MotorSchedule.load(demo).steps == ((0.0, 10.0), (10.0, 90.0))


@pytest.mark.parametrize("name", ["speeds.txt", "speeds", "speeds.yaml"])
def test_unknown_schedule_extensions_are_refused_like_sweep_files(tmp_path, name):
    f = tmp_path / name
    f.write_text("0,10\n")
    with pytest.raises(ValueError) as info:
        MotorSchedule.load(f)
    assert str(f) in str(info.value) and ".csv" in str(info.value) and ".json" in str(info.value)
