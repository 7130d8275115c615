"""scripts/measure_scene_terms.py: in the cruise the rod never reaches itself or the head, so leaving contact out
changes nothing; the Stokes head changes the swim speed (docs/force_terms.md, "What each scene needs")."""

from __future__ import annotations


def test_cruise_without_contact_is_the_same_and_the_stokes_head_is_not(load_script):
    scene = load_script("measure_scene_terms")
    full, no_contact, stokes = (scene.cruise(v) for v in ("full", "no contact", "Stokes head"))
    assert 3e-3 < full["swim_per_turn_m"] < 6e-3
    assert no_contact["swim_per_turn_m"] == full["swim_per_turn_m"]
    assert abs(stokes["swim_per_turn_m"] / full["swim_per_turn_m"] - 1.0) > 0.005
