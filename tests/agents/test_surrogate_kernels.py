"""The compiled kernels of the turn-level surrogate and the rule planner against pure-Python/NumPy oracles (the forms
they replaced): 3-vector arithmetic rounded as NumPy rounds it (``physics.linalg.vec3``), the geometry of a turn
(``agents.turn_geometry``), the paper's line miss and the plan's gate (``agents.candidate_miss``), the sampled look
ahead with its candidate filter (``first_improving_sample``), a leg of the head (``agents.surrogate_legs``), the map
read and the turn (``agents.surrogate_swimmer.turn_outcome``), the features (``agents.residual_planner``), the random
path's heading (``flagellum_env.paths``) and the tracker's projection. A few seconds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.assets import default_turn_map
from agents.candidate_miss import (candidate_frames, candidate_miss, first_improving_sample, line_miss, local_target,
                                   paper_rule_choice, paper_rule_misses, pick_least, target_in_frame, turn_wanted)
from agents.residual_planner import N_FEATURES, ResidualLimits, corrected_turn, turn_features
from agents.surrogate_calibration import SurrogateCalibration, calibration_file
from agents.surrogate_legs import (ACC_REACHED, CROSS, ENERGY, LEG_SIZE, OFF_PATH, OFF_PATH_M, REACH, STATE_SIZE, TIME,
                                   TIME_LIMIT, TERMINATED, TRUNCATED, SegmentFrames, fly_state)
from agents.surrogate_swimmer import SurrogateSwimmer, TurnMapTable
from agents.turn_geometry import angle_between, azimuth, perpendicular_basis, unit, wrap_angle
from agents.turn_map import TurnMap
from agents.turn_planner import BEHIND_PENALTY_M, RulePlanner
from flagellum_env.paths import RandomPathConfig, WaypointPath, _turned_heading, path_from_waypoints, random_path
from flagellum_env.tracking import PathTracker
from physics.linalg.vec3 import dot3, norm3, rowdot3, rownorm3, segment_projection

# NumPy's rounding of a 3-vector product depends on its BLAS and SIMD loops: the kernels reproduce it exactly on
# this project's machines (the surrogate's results are bit-identical to the NumPy code they replaced); elsewhere
# they agree to the last bits.
ULP = dict(rtol=1e-15, atol=1e-300)


@pytest.fixture(scope="module")
def tmap() -> TurnMap:
    return TurnMap.load(default_turn_map("faithful"))


def _vectors(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 3)) * rng.uniform(1e-3, 10.0, (n, 1))


def test_vec3_rounds_as_numpy():
    a, b = _vectors(2000, 1), _vectors(2000, 2)
    np.testing.assert_allclose([dot3(x, y) for x, y in zip(a, b)], [float(x @ y) for x, y in zip(a, b)], **ULP)
    np.testing.assert_allclose([norm3(x) for x in a], np.linalg.norm(a, axis=1), **ULP)
    np.testing.assert_allclose([rowdot3(*x, *y) for x, y in zip(a.tolist(), b.tolist())],
                               np.einsum("ij,ij->i", a, b), **ULP)
    np.testing.assert_allclose([rownorm3(*x) for x in a.tolist()], np.linalg.norm(a, axis=1), **ULP)


def test_the_geometry_is_its_numpy_form_and_refuses_a_zero_vector():
    vs, ws = _vectors(300, 3), _vectors(300, 4)
    for v, w in zip(vs, ws):
        a = v / math.sqrt(float(v @ v))
        helper = np.array([0.0, 0.0, 1.0]) if abs(a[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        e1 = helper - (helper @ a) * a
        e1 = e1 / math.sqrt(float(e1 @ e1))
        e2 = np.cross(a, e1)
        f1, f2 = perpendicular_basis(v)
        np.testing.assert_allclose(f1, e1, **ULP)
        np.testing.assert_allclose(f2, e2, **ULP)
        cos = float(unit(v) @ unit(w))
        assert angle_between(v, w) == pytest.approx(math.acos(min(max(cos, -1.0), 1.0)), rel=1e-14, abs=1e-15)
        assert azimuth(w, v) == pytest.approx(math.atan2(float(w @ e2), float(w @ e1)), rel=1e-14, abs=1e-15)
        assert wrap_angle(float(v[0])) == math.pi - (math.pi - float(v[0])) % (2.0 * math.pi)
    for bad in (np.zeros(3), np.array([np.inf, 0.0, 0.0])):
        for call in (lambda: unit(bad), lambda: perpendicular_basis(bad), lambda: angle_between(bad, vs[0]),
                     lambda: angle_between(vs[0], bad), lambda: azimuth(vs[0], bad)):
            with pytest.raises(ValueError, match="cannot normalise"):
                call()


def _numpy_line_miss(starts, directions, target, behind_penalty):
    """The paper's line miss in NumPy (``agents.turn_planner._line_miss`` before it was compiled)."""
    rel = target - starts
    along = np.einsum("ij,ij->i", rel, directions)
    lateral = np.linalg.norm(rel - along[:, None] * directions, axis=1)
    return np.where(along > 0.0, lateral, np.linalg.norm(rel, axis=1) + behind_penalty)


def test_the_line_miss_and_the_plans_gate_are_their_numpy_forms(tmap):
    rng = np.random.default_rng(5)
    starts, dirs = rng.normal(0, 0.05, (500, 3)), _vectors(500, 6)
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    target = rng.normal(0, 0.1, 3)
    np.testing.assert_allclose(line_miss(starts, dirs, target, 0.05), _numpy_line_miss(starts, dirs, target, 0.05),
                               **ULP)
    planner = RulePlanner(tmap, None, 0.1, 0.015, None)
    _, theta, psi, off = planner._candidates
    beta = planner._burst_phases
    frames = candidate_frames(theta, psi, off, beta)
    hit, min_turn = planner.config.hit_fraction * 0.015, planner.config.min_turn_deg
    seen = set()
    for head, d in zip(starts[:200], dirs[:200]):
        miss0 = float(_numpy_line_miss(head[None], d[None], target, BEHIND_PENALTY_M)[0])
        want = 0 if miss0 < hit or math.degrees(angle_between(d, target - head)) < min_turn else 1
        grid = np.full((len(theta), len(beta)), np.nan)
        got, got0 = paper_rule_misses(head, d, target, frames, BEHIND_PENALTY_M, hit, min_turn, grid)
        assert (got, got0) == (want, pytest.approx(miss0, rel=1e-14)) and turn_wanted(miss0, d, target - head, hit,
                                                                                   min_turn) == want
        k, best = pick_least(grid, miss0, planner.config.improvement_m) if want else (-1, math.nan)
        assert paper_rule_choice(head, d, target, frames, BEHIND_PENALTY_M, hit, min_turn,
                                 planner.config.improvement_m)[::2] == (want, k) and (k < 0 or
                                                                                      grid.flat[k] == best)
        if want:
            e1, e2 = perpendicular_basis(d)
            np.testing.assert_array_equal(grid, candidate_miss(frames, *local_target(head, d, e1, e2, target),
                                                               BEHIND_PENALTY_M))
            assert target_in_frame(head, d, target) == local_target(head, d, e1, e2, target)
        seen.add(want)
    assert seen == {0, 1}
    assert turn_wanted(1.0, dirs[0], np.zeros(3), hit, min_turn) == -1  # no direction to the target: no angle


def _sampled_oracle(frames, q0, q1, q2, behind_penalty, improvement, step_m, n_max):
    """``first_improving_sample`` by its definition: every candidate's miss at every sample."""
    for k in range(1, n_max + 1):
        m0 = q0 - k * step_m
        straight = (math.sqrt(q1 * q1 + q2 * q2) if m0 > 0.0
                    else math.sqrt(m0 * m0 + q1 * q1 + q2 * q2) + behind_penalty)
        if candidate_miss(frames, m0, q1, q2, behind_penalty).min() <= straight - improvement:
            return k
    return -1


def test_the_sampled_look_ahead_is_its_definition(tmap):
    """The filter of candidates that cannot pass changes no answer: targets behind and beside the swimmer, each
    answer from -1 to late samples met."""
    planner = RulePlanner(tmap, None, 0.1, 0.015, None)
    _, theta, psi, off = planner._candidates
    frames = candidate_frames(theta, psi, off, planner._burst_phases)
    rng = np.random.default_rng(7)
    answers = []
    for _ in range(300):
        q = (rng.uniform(-0.3, 0.05), rng.normal(0, 0.06), rng.normal(0, 0.06))
        step = rng.uniform(0.001, 0.01)
        k = first_improving_sample(frames, *q, BEHIND_PENALTY_M, 0.005, step, 20)
        assert k == _sampled_oracle(frames, *q, BEHIND_PENALTY_M, 0.005, step, 20)
        answers.append(k)
    assert -1 in answers and 1 in answers and max(answers) > 3


# --- a leg: the compiled kernel against the Python loop it replaced -------------------------------------------------
_GAUSS_X = (0.5 - 0.5 * math.sqrt(0.6), 0.5, 0.5 + 0.5 * math.sqrt(0.6))
_GAUSS_W = (5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0)


def _oracle_error(path: WaypointPath, index: int, x) -> float:
    v = path.vertices
    i = min(index, path.n_waypoints - 1)
    a, length = v[i].tolist(), float(path.segment_lengths[i])
    u = ((v[i + 1] - v[i]) / path.segment_lengths[i]).tolist()
    r = [x[c] - a[c] for c in range(3)]
    s = min(max(r[0] * u[0] + r[1] * u[1] + r[2] * u[2], 0.0), length)
    e = [r[c] - s * u[c] for c in range(3)]
    return math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])


def _oracle_entry(a, v, w, radius):
    q = [a[c] - w[c] for c in range(3)]
    aa = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    bb = 2.0 * (q[0] * v[0] + q[1] * v[1] + q[2] * v[2])
    cc = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] - radius * radius
    if cc <= 0.0:
        return 0.0, 0.0
    if aa <= 0.0:
        return None
    disc = bb * bb - 4.0 * aa * cc
    if disc < 0.0:
        return None
    s = (-bb - math.sqrt(disc)) / (2.0 * aa)
    if not 0.0 <= s <= 1.0:
        return None
    return s, min(max(-bb / (2.0 * aa), 0.0), 1.0)


def _oracle_leg(tracker, start, end, duration_s, time_s, time_limit_s, off_path_m, stop_at_waypoint):
    """(end, duration, reached, cross integral, off path, timed out): ``fly_state``'s leg in Python."""
    path = tracker.path
    a, b = start.tolist(), end.tolist()
    timed_out = False
    if duration_s > 0.0 and time_s + duration_s > time_limit_s:
        frac = max(time_limit_s - time_s, 0.0) / duration_s
        b = [a[c] + frac * (b[c] - a[c]) for c in range(3)]
        duration_s, timed_out = duration_s * frac, True
    flown, reached, cross, left, grazed = 0.0, 0, 0.0, duration_s, False
    while True:
        v = [b[c] - a[c] for c in range(3)]
        index = tracker.index
        hit = None if tracker.done or grazed else _oracle_entry(a, v, path.waypoints[index].tolist(),
                                                               tracker.reach_radius_m)
        s = 1.0 if hit is None else hit[0] + 0.01 * (hit[1] - hit[0])
        piece, total = left * s, 0.0
        for x, wgt in zip(_GAUSS_X, _GAUSS_W):
            xs = x * s
            e = _oracle_error(path, index, [a[c] + xs * v[c] for c in range(3)])
            if e > off_path_m:
                return [a[c] + xs * v[c] for c in range(3)], flown + piece * x, reached, cross + e * piece * x, True, \
                    False
            total += wgt * e
        p = [a[c] + s * v[c] for c in range(3)]
        cross += total * piece
        flown += piece
        left -= piece
        if hit is None:
            break
        n = tracker.update(np.array(p))
        reached += n
        a, grazed = p, n == 0
        if tracker.done or (stop_at_waypoint and n > 0) or left <= 0.0:
            break
    off = not tracker.done and _oracle_error(path, tracker.index, p) > off_path_m
    return p, flown, reached, cross, off, timed_out and not tracker.done and not off and left <= 1e-12


def test_a_compiled_leg_is_the_python_leg():
    """Random legs over random paths (waypoints reached, passed, grazed; off the path; out of time)."""
    rng = np.random.default_rng(11)
    kinds = set()
    for trial in range(400):
        path = random_path(rng, RandomPathConfig(n_waypoints=4, segment_length_m=(0.02, 0.05), planar=False))
        reach = float(rng.uniform(0.005, 0.02))
        fast, slow = PathTracker(path, reach), PathTracker(path, reach)
        index = int(rng.integers(0, 4))
        fast.mark_reached(index)
        slow.mark_reached(index)
        start = path.vertices[index] + rng.normal(0, 0.01, 3)
        end = start + rng.normal(0, 0.05, 3)
        args = (start, end, float(rng.uniform(0.5, 20.0)), float(rng.uniform(0, 50)), 60.0,
                float(rng.uniform(0.01, 0.05)), bool(rng.integers(2)))
        start, end, duration_s, time_s, limit_s, off_m, stop = args
        state, consts = np.zeros(STATE_SIZE), np.zeros(LEG_SIZE)
        state[0:3], state[TIME] = start, time_s
        consts[[REACH, TIME_LIMIT, OFF_PATH_M]] = reach, limit_s, off_m
        # a power of 1 W: the energy is the duration flown
        got, how = fly_state(state, *end.tolist(), duration_s, 1.0, 0.0, False, stop, fast.index,
                             SegmentFrames(fast).table, consts)
        fast.mark_reached(got)
        p, flown, reached, cross, off, timed_out = _oracle_leg(slow, *args)
        assert state[0:3].tolist() == p and (state[ENERGY], got, state[CROSS], bool(state[OFF_PATH]),
                                             how == TRUNCATED) == (flown, reached, cross, off, timed_out), trial
        assert state[ACC_REACHED] == reached and (how == TERMINATED) == (slow.done or off)
        assert fast.index == slow.index
        kinds.update({("reached", reached > 0), ("off", off), ("timed_out", timed_out)})
    assert kinds >= {("reached", True), ("off", True), ("timed_out", True), ("reached", False)}
    with pytest.raises(ValueError, match="waypoints left"):
        fast.mark_reached(path.n_waypoints + 1)


# --- the swimmer's turn, the features, the path, the tracker --------------------------------------------------------
def test_the_map_read_and_the_turn_are_their_python_forms(tmap):
    """The bilinear read (bisect on the burst lengths and the periodic phases) and the turn's geometry as they were
    in Python, with and without a randomised map (``direction_bias_rad``, ``turn_scale``)."""
    tab = TurnMapTable(tmap)
    sw = SurrogateSwimmer(tmap, SurrogateCalibration.load(calibration_file("faithful")), tab)
    t, ph = tab.t_c.tolist(), tab.phases.tolist()
    rng = np.random.default_rng(13)
    for trial in range(300):
        t_c, beta = float(rng.uniform(-0.2, t[-1] * 1.1)), float(rng.uniform(-10.0, 10.0))
        sw.direction_bias_rad, sw.turn_scale = (0.0, 1.0) if trial % 2 else (float(rng.normal()), 0.8)
        d = unit(rng.normal(size=3))
        out = sw.turn(d, t_c, beta)
        # the oracle
        t_map = t_c * sw.time_factor
        scale, in_range = 1.0, 0.0 <= t_map <= t[-1] + 1e-9
        if t_map <= t[0]:
            k0 = k1 = 0
            w_t, scale = 0.0, max(t_map, 0.0) / t[0]
        elif t_map >= t[-1]:
            k0 = k1 = len(t) - 1
            w_t = 0.0
        else:
            k1 = int(np.searchsorted(t, t_map, side="right"))
            k0 = k1 - 1
            w_t = (t_map - t[k0]) / (t[k1] - t[k0])
        b = beta % (2.0 * math.pi)
        j1 = int(np.searchsorted(ph, b, side="right")) % len(ph)
        j0 = (j1 - 1) % len(ph)
        w_b = ((b - ph[j0]) % (2.0 * math.pi)) / ((ph[j1] - ph[j0]) % (2.0 * math.pi) or 2.0 * math.pi)
        c = tab.channels
        th, pc, ps, o0, o1, o2, relax, ratio = ((1.0 - w_t) * ((1.0 - w_b) * c[k0, j0] + w_b * c[k0, j1])
                                                + w_t * ((1.0 - w_b) * c[k1, j0] + w_b * c[k1, j1])).tolist()
        theta, psi, ref = scale * th, math.atan2(ps, pc), beta
        if sw.direction_bias_rad != 0.0 or sw.turn_scale != 1.0:
            theta = min(max(sw.turn_scale * theta, 0.0), math.pi)
            psi, ref = wrap_angle(psi + sw.direction_bias_rad), beta + sw.direction_bias_rad
        e1, e2 = perpendicular_basis(d)
        h = (math.cos(theta) * d + math.sin(theta) * (math.cos(beta + psi) * e1 + math.sin(beta + psi) * e2))
        e_ref = math.cos(ref) * e1 + math.sin(ref) * e2
        disp = o0 * d + o1 * e_ref + o2 * np.cross(d, e_ref)
        assert (out.theta_rad, out.psi_rad, out.end_ratio, out.in_range) == (theta, psi, ratio, in_range)
        assert out.relax_s == relax * sw.tau_ratio
        np.testing.assert_allclose(out.heading, h / np.linalg.norm(h), rtol=0, atol=1e-15)
        np.testing.assert_allclose(out.displacement, disp, rtol=0, atol=1e-15)


def _oracle_features(plan, targets, reach, ratio, time_left, previous, n_turns, max_theta):
    """``turn_features`` as it was in Python."""
    d = np.asarray(plan["heading"], dtype=np.float64)
    to_target = targets[0]
    after = targets[1] - targets[0] if len(targets) > 1 else np.zeros(3)
    next_len = float(np.linalg.norm(after))
    corner = angle_between(to_target, after) if next_len > 1e-9 else 0.0
    had, turn_ratio, az_err = 0.0, 1.0, 0.0
    if previous is not None and "predicted_theta_deg" in previous:
        d0 = np.asarray(previous["heading"], dtype=np.float64)
        had = 1.0
        turn_ratio = math.degrees(angle_between(d0, d)) / max(previous["predicted_theta_deg"], 1.0)
        az_err = math.degrees(wrap_angle(azimuth(d, d0) - previous["predicted_azimuth"])) / 90.0
    f = np.array([plan["theta_deg"] / max_theta, plan["t_c"] / 10.0, plan["predicted_miss_m"] / reach,
                  plan["miss_straight_m"] / reach, float(np.linalg.norm(to_target)) / 0.1,
                  math.degrees(angle_between(d, to_target)) / 90.0, math.degrees(corner) / 90.0, next_len / 0.1,
                  ratio, time_left, n_turns / 5.0, had, turn_ratio, az_err])
    f = np.clip(f, -10.0, 10.0)
    f[np.isnan(f)] = 0.0
    return f.astype(np.float32)


def test_the_compiled_features_are_the_python_features():
    rng = np.random.default_rng(17)
    for trial in range(200):
        plan = {"theta_deg": float(rng.uniform(0, 150)), "t_c": float(rng.uniform(0, 4)),
                "predicted_miss_m": float(rng.uniform(0, 0.2)), "miss_straight_m": float(rng.uniform(0, 1.0)),
                "heading": unit(rng.normal(size=3)).tolist()}
        previous = None if trial % 3 == 0 else {"heading": unit(rng.normal(size=3)).tolist(),
                                                "predicted_theta_deg": float(rng.uniform(0, 120)),
                                                "predicted_azimuth": float(rng.uniform(-4, 4))}
        targets = rng.normal(0, 0.1, (2, 3))
        if trial % 5 == 0:
            targets[1] = targets[0]  # the last segment: no corner
        args = (plan, targets, 0.015, float(rng.uniform(0.5, 1)), float(rng.uniform(0, 1)), previous,
                int(rng.integers(0, 9)), 140.0)
        got = turn_features(*args)
        assert got.dtype == np.float32 and got.shape == (N_FEATURES,)
        np.testing.assert_allclose(got, _oracle_features(*args), rtol=1e-6, atol=1e-7)
    with pytest.raises(ValueError, match="cannot normalise"):
        turn_features(plan, np.zeros((2, 3)), 0.015, 1.0, 1.0, None, 0, 140.0)


def test_the_random_paths_heading_is_rodrigues_rotation():
    rng = np.random.default_rng(19)
    for _ in range(500):
        h = unit(rng.normal(size=3))
        if rng.random() < 0.2:
            h = unit(np.array([0.01, 0.0, 1.0]))  # near +z: the helper is +y
        phi, angle = float(rng.uniform(0, 2 * math.pi)), float(rng.uniform(-math.pi, math.pi))
        for planar in (True, False):
            if planar:
                axis = np.array([0.0, 0.0, 1.0])
            else:
                helper = np.array([0.0, 0.0, 1.0]) if abs(h[2]) < 0.9 else np.array([0.0, 1.0, 0.0])
                e1 = np.cross(h, helper)
                e1 /= np.linalg.norm(e1)
                axis = math.cos(phi) * e1 + math.sin(phi) * np.cross(h, e1)
            c, s = math.cos(angle), math.sin(angle)
            r = h * c + np.cross(axis, h) * s + axis * float(axis @ h) * (1.0 - c)
            np.testing.assert_allclose(_turned_heading(*h.tolist(), planar, phi, angle), r / np.linalg.norm(r),
                                       rtol=0, atol=1e-15)
            assert _turned_heading(*h.tolist(), planar, phi, angle) == _oracle_turned_heading(*h.tolist(), planar,
                                                                                               phi, angle)


def test_a_paths_summaries_and_the_trackers_projection():
    path = random_path(np.random.default_rng(23), RandomPathConfig(n_waypoints=5, planar=False))
    vertices = np.vstack([np.zeros((1, 3)), path.waypoints])
    np.testing.assert_array_equal(path.vertices, vertices)
    np.testing.assert_array_equal(path.segment_lengths, np.linalg.norm(np.diff(vertices, axis=0), axis=1))
    assert path.length_m == float(path.segment_lengths.sum()) and path.n_waypoints == 5
    assert not (path.vertices.flags.writeable or path.segment_lengths.flags.writeable)
    same = path_from_waypoints(path.waypoints.tolist(), name="random")  # the checked loop, not the array's check
    np.testing.assert_array_equal(same.vertices, path.vertices)
    tracker = PathTracker(path, 0.01)
    rng = np.random.default_rng(29)
    for x in rng.normal(0, 0.1, (200, 3)):
        a, b = path.vertices[0], path.vertices[1]
        u = (b - a) / path.segment_lengths[0]
        s = min(max(float((x - a) @ u), 0.0), float(path.segment_lengths[0]))
        got = segment_projection(x, a, b, float(path.segment_lengths[0]))
        assert got[0] == pytest.approx(s, rel=1e-15, abs=1e-18)
        np.testing.assert_allclose(got[1:], a + s * u, **ULP)
        assert tracker.progress(x) == pytest.approx(s, rel=1e-15, abs=1e-18)
    np.testing.assert_array_equal(tracker.targets(3), path.waypoints[:3])
    tracker.mark_reached(4)
    np.testing.assert_array_equal(tracker.targets(3), path.waypoints[[4, 4, 4]])


def test_theta_for_reads_the_rising_branch(tmap):
    t, y = tmap.rising_branch()
    for t_c in np.linspace(-0.5, t[-1] + 1.0, 57):
        assert tmap.theta_for(float(t_c)) == float(np.interp(t_c, t, y))


def test_the_compiled_map_reads_and_correction_are_their_numpy_forms(tmap):
    """``theta_for``, ``psi_for`` (compiled np.interp) and ``corrected_turn`` against np.interp and the formulas, at
    random burst lengths and on the measured ones."""
    rng = np.random.default_rng(4)
    t, y, tcs, un = tmap.turn_curves()
    limits = ResidualLimits()
    for t_c in np.concatenate([rng.uniform(-0.5, 11.0, 3000), t, tcs, np.nextafter(tcs, 0.0)]):
        t_c = float(t_c)
        assert tmap.theta_for(t_c) == float(np.interp(t_c, t, y))
        psi = math.degrees(wrap_angle(math.radians(float(np.interp(t_c, tcs, un)))))
        assert tmap.psi_for(t_c) == psi
        phase, a0, a1 = float(rng.uniform(-4.0, 4.0)), float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1))
        t2 = t_c * (1.0 + a0 * limits.max_dtc_fraction)
        p2 = wrap_angle(phase + math.radians(a1 * limits.max_dphase_deg))
        want = (t2, p2, float(np.interp(t2, t, y)),
                wrap_angle(p2 + math.radians(math.degrees(wrap_angle(math.radians(float(np.interp(t2, tcs, un))))))))
        assert corrected_turn(t_c, phase, a0, a1, limits.max_dtc_fraction, limits.max_dphase_deg, t, y, tcs,
                              un) == want


def test_the_compiled_choice_is_argmin_and_the_improvement_test():
    """``pick_least``: np.argmin's index (the first of equal misses, a NaN before all) and the rule's test."""
    rng = np.random.default_rng(2)
    for trial in range(200):
        miss = rng.integers(0, 5, (4, 6)).astype(float) * 0.01  # ties
        if trial % 5 == 0:
            miss.flat[rng.integers(miss.size)] = np.nan
        straight = float(rng.uniform(0.0, 0.06))
        k, best = pick_least(miss, straight, 0.005)
        want = int(miss.argmin())
        assert (k, best) == ((want if not miss.flat[want] > straight - 0.005 else -1), miss.flat[want]) or (
            math.isnan(best) and k == want and math.isnan(miss.flat[want]))


def _oracle_turned_heading(h0, h1, h2, planar, phi, angle):
    """``_turned_heading`` in Python (its formulas, BLAS's rounding of the dot products: ``dot3s``)."""
    if planar:
        x0, x1, x2 = 0.0, 0.0, 1.0
    else:
        g0, g1, g2 = (0.0, 0.0, 1.0) if abs(h2) < 0.9 else (0.0, 1.0, 0.0)
        a0, a1, a2 = h1 * g2 - h2 * g1, h2 * g0 - h0 * g2, h0 * g1 - h1 * g0
        n = math.sqrt(float(np.array([a0, a1, a2]) @ np.array([a0, a1, a2])))
        a0, a1, a2 = a0 / n, a1 / n, a2 / n
        b0, b1, b2 = h1 * a2 - h2 * a1, h2 * a0 - h0 * a2, h0 * a1 - h1 * a0
        cp, sp = math.cos(phi), math.sin(phi)
        x0, x1, x2 = cp * a0 + sp * b0, cp * a1 + sp * b1, cp * a2 + sp * b2
    c, s = math.cos(angle), math.sin(angle)
    k0, k1, k2 = x1 * h2 - x2 * h1, x2 * h0 - x0 * h2, x0 * h1 - x1 * h0
    p = float(np.array([x0, x1, x2]) @ np.array([h0, h1, h2]))
    r0, r1, r2 = h0 * c + k0 * s + x0 * p * (1.0 - c), h1 * c + k1 * s + x1 * p * (1.0 - c), \
        h2 * c + k2 * s + x2 * p * (1.0 - c)
    n = math.sqrt(float(np.array([r0, r1, r2]) @ np.array([r0, r1, r2])))
    return r0 / n, r1 / n, r2 / n


def _oracle_random_path(rng, cfg):
    """``random_path`` drawing each number by itself (``Generator.uniform`` and ``random`` in turn)."""
    lo, hi = cfg.segment_length_m
    max_turn, min_turn = math.radians(cfg.max_turn_deg), math.radians(cfg.min_turn_deg)
    h, p, pts = (1.0, 0.0, 0.0), np.zeros(3), []
    n = cfg.n_waypoints if not isinstance(cfg.n_waypoints, tuple) else int(rng.integers(cfg.n_waypoints[0],
                                                                                            cfg.n_waypoints[1] + 1))
    for _ in range(n):
        length = float(rng.uniform(lo, hi))
        if cfg.min_turn_deg > 0.0:
            angle = float(rng.uniform(min_turn, max_turn)) * (1.0 if rng.random() < 0.5 else -1.0)
        else:
            angle = float(rng.uniform(-max_turn, max_turn))
        phi = 0.0 if cfg.planar else float(rng.uniform(0.0, 2.0 * math.pi))
        h = _oracle_turned_heading(*h, cfg.planar, phi, angle)
        p = np.array([p[0] + length * h[0], p[1] + length * h[1], p[2] + length * h[2]])
        pts.append(p)
    reach = None if cfg.reach_radius_m is None else float(rng.uniform(*cfg.reach_radius_m))
    return np.array(pts), reach


def test_the_random_paths_numbers_drawn_at_once_are_those_drawn_one_by_one():
    for cfg in (RandomPathConfig(), RandomPathConfig(n_waypoints=(1, 7), planar=False),
                RandomPathConfig(min_turn_deg=30.0, max_turn_deg=150.0, planar=False, reach_radius_m=(0.01, 0.02)),
                RandomPathConfig(min_turn_deg=30.0, max_turn_deg=150.0, segment_length_m=(0.12, 0.2))):
        for seed in range(40):
            fast, slow = np.random.default_rng(seed), np.random.default_rng(seed)
            for _ in range(3):
                path, (pts, reach) = random_path(fast, cfg), _oracle_random_path(slow, cfg)
                assert np.array_equal(path.waypoints, pts) and path.reach_radius_m == reach
            assert fast.random() == slow.random()
