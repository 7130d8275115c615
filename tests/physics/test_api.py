"""The public API of ``physics`` (its ``__init__``): the names, ``configure`` and the run loop ``advance``."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import physics
from physics import NumericsConfig, Simulator, SwimmerParams, advance, configure
from physics.params import RPM_TO_RAD_S, apply_overrides
from physics.presets import apply_preset, preset_names


def test_every_public_name_resolves():
    for name in physics.__all__:
        assert getattr(physics, name) is not None
    with pytest.raises(AttributeError):
        physics.no_such_name  # noqa: B018


def test_configure_is_defaults_then_preset_then_overrides():
    assert configure() == (SwimmerParams(), NumericsConfig())
    for name in preset_names():
        assert configure(name) == apply_preset(name)
    p, n = configure("faithful", {"head_radius": "0.01", "dt": 0.005, "head_rotation": "fixed"})
    p2, n2 = apply_overrides(*apply_preset("faithful"), {"head_radius": "0.01", "dt": "0.005", "head_rotation": "fixed"})
    assert (p, n) == (p2, n2) and p.head_radius == 0.01 and n.dt == 0.005


def test_configure_routes_every_field_by_name():
    """No list of names is written down: every field of both dataclasses can be set."""
    base_p, base_n = SwimmerParams(), NumericsConfig()
    for cls, base in ((SwimmerParams, base_p), (NumericsConfig, base_n)):
        for f in dataclasses.fields(cls):
            p, n = configure(None, {f.name: getattr(base, f.name)})
            assert getattr(p if cls is SwimmerParams else n, f.name) == getattr(base, f.name)


@pytest.mark.parametrize("overrides, fragment", [({"no_such": 1}, "'no_such'"), ({"no_such": "1"}, "'no_such'"),
                                                 ({"viscosity": -1.0}, "viscosity")])
def test_configure_names_what_is_wrong(overrides, fragment):
    with pytest.raises(ValueError, match=fragment):
        configure("faithful", overrides)


@pytest.mark.parametrize("name, why", [("coarse", "slower than 'faithful' and wrong: it does not buckle")])
def test_retired_presets_are_refused_on_one_line_naming_the_replacement(name, why):
    from physics.presets import check_preset

    assert name not in preset_names()
    for call in (lambda: configure(name), lambda: apply_preset(name), lambda: check_preset(name)):
        with pytest.raises(ValueError) as err:
            call()
        msg = str(err.value)
        assert "\n" not in msg
        assert msg == (f"preset {name!r} was retired ({why}; docs/presets.md); use 'faithful' (the default), or "
                       "FlagellumTurn-surrogate-v0 / FlagellumBurst-surrogate-v0 for a cheap turn-level swimmer")
    with pytest.raises(ValueError, match=r"preset='turbo' is not allowed; choose one of \['reference', 'paper', 'faithful', 'fast'\]"):
        configure("turbo")


def test_removed_parameters_are_refused_on_one_line_saying_why():
    """``anderson_depth`` (Anderson mixing) was removed: every way of naming it gets the same one-line reason."""
    why = ("parameter 'anderson_depth' was removed (Anderson mixing of the chord iteration cost more CPU than it "
           "saved; the chord and Newton iterations run compiled without it (docs/time_integration.md)); drop it")
    for call in (lambda: configure("faithful", {"anderson_depth": 0}), lambda: configure(None, {"anderson_depth": "4"}),
                 lambda: apply_overrides(SwimmerParams(), NumericsConfig(), {"anderson_depth": "0"})):
        with pytest.raises(ValueError) as err:
            call()
        assert str(err.value) == why
    assert "anderson_depth" not in {f.name for f in dataclasses.fields(NumericsConfig)}


@pytest.fixture(scope="module")
def small():
    return configure("faithful", {"n_nodes": 25})


def _state(sim: Simulator) -> dict:
    return sim.get_state()


def test_advance_takes_the_steps_of_simulator_advance(small):
    a, b = Simulator(*small), Simulator(*small)
    for sim in (a, b):
        sim.set_motor_speed(30 * RPM_TO_RAD_S)
    a.advance(0.1)
    assert advance(b, 0.1) == round(0.1 / small[1].dt)
    sa, sb = _state(a), _state(b)
    for k, v in sa.items():
        assert np.array_equal(np.asarray(v), np.asarray(sb[k])), k


def test_advance_calls_back_after_each_step_and_stops_when_asked(small):
    sim = Simulator(*small)
    sim.set_motor_speed(30 * RPM_TO_RAD_S)
    seen = []

    def on_step(s, k):
        seen.append((k, s.step_count))
        return k == 3

    assert advance(sim, steps=10, on_step=on_step) == 3
    assert seen == [(1, 1), (2, 2), (3, 3)]
    with pytest.raises(ValueError, match="exactly one"):
        advance(sim, 1.0, steps=2)


# --- issue 24: the public methods refuse what the command line refuses ----------------------------------
@pytest.mark.parametrize("params, numerics, name", [("x", None, "params='x'"), (None, {"dt": 0.01}, "numerics=")])
def test_simulator_refuses_arguments_of_the_wrong_type_naming_them(params, numerics, name):
    with pytest.raises(ValueError) as info:
        Simulator(params, numerics)
    assert name in str(info.value) and "allowed" in str(info.value)


@pytest.mark.parametrize("omega", [-1.0, -1e-9, float("nan"), float("inf"), 2000.0, True, "10"])
def test_motor_speed_follows_the_command_lines_rule(small, omega):
    sim = Simulator(*small)
    with pytest.raises(ValueError, match=r"allowed: a finite speed >= 0 and <= 1047.2 rad/s \(10000 rpm\)"):
        sim.set_motor_speed(omega)
    sim.set_motor_speed(0.0)
    sim.set_motor_speed(150 * RPM_TO_RAD_S)


@pytest.mark.parametrize("call, fragment", [
    (lambda sim: sim.advance(-1), "duration_s=-1 is not allowed"),
    (lambda sim: sim.advance(float("nan")), "duration_s=nan"),
    (lambda sim: advance(sim, -1.0), "duration_s=-1.0 is not allowed"),
    (lambda sim: advance(sim, steps=-3), "steps=-3 is not allowed"),
    (lambda sim: advance(sim, steps=1.5), "steps=1.5 is not allowed"),
])
def test_negative_advances_are_refused_not_silently_ignored(small, call, fragment):
    sim = Simulator(*small)
    with pytest.raises(ValueError, match="allowed") as info:
        call(sim)
    assert fragment in str(info.value) and sim.step_count == 0


def test_advance_by_a_huge_step_count_does_not_build_a_list_first(small):
    sim = Simulator(*small)
    assert advance(sim, steps=10**12, on_step=lambda s, k: k == 2) == 2  # no MemoryError: the steps are lazy
    assert advance(sim, steps=0) == 0
