"""Motor speed schedules: piecewise-constant omega(t) in rpm.

A schedule is a list of steps ``(time_s, omega_rpm)``: from ``time_s`` on, the motor turns at
``omega_rpm`` until the next step. The first step starts at t = 0, times strictly increase,
and every speed is finite and in [0, ``MAX_RPM``].

Files (``MotorSchedule.load``):

* CSV: optional header ``time_s,omega_rpm``, then two numbers per row; blank lines and
  lines starting with ``#`` are skipped.
* JSON: ``[[t, w], ...]`` or ``{"steps": [[t, w], ...]}``.
"""

from __future__ import annotations

import bisect
import csv
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from numbers import Real
from pathlib import Path
from typing import Any

from physics.params import RPM_TO_RAD_S
from physics.validation import require_finite

MAX_RPM = 10000.0
#: File kinds ``MotorSchedule.load`` reads.
SCHEDULE_SUFFIXES = (".csv", ".json")
CSV_HEADER = ("time_s", "omega_rpm")


def _as_number(raw: Any, what: str, where: str) -> float:
    """Convert a JSON/CSV cell to float; ValueError naming the place and the value."""
    if isinstance(raw, bool) or not isinstance(raw, (Real, str)):
        raise ValueError(f"{where}: {what}={raw!r} is not a number")
    try:
        return float(raw)
    except ValueError:
        raise ValueError(f"{where}: {what}={raw!r} is not a number") from None


def _check_steps(steps: Sequence[tuple[float, float]], labels: Sequence[str]) -> None:
    """Validate times and speeds; ``labels[i]`` says where step i came from."""
    if len(steps) == 0:
        raise ValueError("a motor schedule needs at least one step (time_s, omega_rpm)")
    prev = -math.inf
    for (t, w), where in zip(steps, labels):
        if not math.isfinite(t):
            raise ValueError(f"{where}: time_s={t!r} must be a finite number of seconds")
        require_finite(f"{where}: omega_rpm", w, 0.0, MAX_RPM, unit="rpm")
        if prev == -math.inf and t != 0.0:
            raise ValueError(f"{where}: the first step must start at time_s=0, got time_s={t!r}")
        if t <= prev:
            raise ValueError(f"{where}: time_s={t!r} must be greater than the previous step's time_s={prev!r}")
        prev = t


@dataclass(frozen=True)
class MotorSchedule:
    """Piecewise-constant motor speed.

    steps: ((time_s, omega_rpm), ...), seconds and revolutions per minute; first time 0,
    times strictly increasing, speeds in [0, MAX_RPM].
    """

    steps: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        try:
            steps = tuple((float(t), float(w)) for t, w in self.steps)
        except (TypeError, ValueError):
            raise ValueError(f"steps={self.steps!r} must be a sequence of (time_s, omega_rpm) number pairs") from None
        _check_steps(steps, [f"step {i}" for i in range(len(steps))])
        object.__setattr__(self, "steps", steps)

    # --- construction ---------------------------------------------------------------
    @classmethod
    def constant(cls, omega_rpm: float) -> MotorSchedule:
        """A constant speed ``omega_rpm`` (rpm) from t = 0 on."""
        return cls(((0.0, require_finite("omega_rpm", omega_rpm, 0.0, MAX_RPM, unit="rpm")),))

    @classmethod
    def load(cls, path: str | Path) -> MotorSchedule:
        """Read a schedule from a ``.json`` or ``.csv`` file (other suffixes are refused, as sweep files are).

        Raises ValueError naming the file, the row (CSV line number or JSON index) and the bad value.
        """
        path = Path(path)
        if path.suffix.lower() not in SCHEDULE_SUFFIXES:
            raise ValueError(f"schedule file {str(path)!r} is not allowed; allowed: a .csv file ('time_s,omega_rpm' "
                             "rows) or a .json file ([[t, w], ...])")
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            raise ValueError(f"cannot read schedule file {str(path)!r}: {reason}") from None
        if path.suffix.lower() == ".json":
            steps, labels = _parse_json(text, str(path))
        else:
            steps, labels = _parse_csv(text, str(path))
        _check_steps(steps, labels)
        return cls(tuple(steps))

    # --- queries --------------------------------------------------------------------
    @property
    def times_s(self) -> tuple[float, ...]:
        """Start time of each step, s."""
        return tuple(t for t, _ in self.steps)

    @property
    def is_constant(self) -> bool:
        """True when the speed never changes."""
        return len({w for _, w in self.steps}) == 1

    def omega_rpm_at(self, t_s: float) -> float:
        """Motor speed at time ``t_s`` (s), rpm; times before 0 get the first speed."""
        if not math.isfinite(t_s):
            raise ValueError(f"t_s={t_s!r} must be a finite time in seconds")
        i = bisect.bisect_right(self.times_s, t_s) - 1
        return self.steps[max(i, 0)][1]

    def omega_rad_s_at(self, t_s: float) -> float:
        """Motor speed at time ``t_s`` (s), rad/s."""
        return self.omega_rpm_at(t_s) * RPM_TO_RAD_S

    def spans(self, duration_s: float, dt: float) -> list[tuple[float, float]]:
        """(span s, omega rad/s) pieces covering [0, duration_s]: steps of at most dt that end at every switch
        time, so no step straddles a switch (for the adaptive integrator, whose steps may have any length)."""
        cuts = {k * dt for k in range(1, int(math.floor(duration_s / dt + 1e-9)) + 1)}
        cuts |= {t for t in self.times_s if 0.0 < t < duration_s}
        cuts.add(duration_s)
        edges = [0.0] + sorted(c for c in cuts if c <= duration_s)
        out = []
        for a, b in zip(edges[:-1], edges[1:]):
            if b - a > 1e-9 * dt:
                out.append((b - a, self.omega_rad_s_at(0.5 * (a + b))))
        return out

    def mean_omega_rpm(self, duration_s: float) -> float:
        """Time-averaged speed over [0, duration_s], rpm."""
        if not (math.isfinite(duration_s) and duration_s > 0.0):
            raise ValueError(f"duration_s={duration_s!r} must be a finite time > 0 s")
        total = 0.0
        for i, (t, w) in enumerate(self.steps):
            end = self.steps[i + 1][0] if i + 1 < len(self.steps) else math.inf
            total += w * max(0.0, min(end, duration_s) - t)
        return total / duration_s

    def to_list(self) -> list[list[float]]:
        """The steps as ``[[time_s, omega_rpm], ...]`` (JSON-ready)."""
        return [[t, w] for t, w in self.steps]


def _parse_csv(text: str, name: str) -> tuple[list[tuple[float, float]], list[str]]:
    steps: list[tuple[float, float]] = []
    labels: list[str] = []
    first = True
    for lineno, row in enumerate(csv.reader(text.splitlines()), start=1):
        cells = [c.strip() for c in row]
        if not cells or all(c == "" for c in cells) or cells[0].startswith("#"):
            continue
        where = f"{name}: row {lineno}"
        if first:
            first = False
            if tuple(c.lower() for c in cells) == CSV_HEADER:
                continue
            if len(cells) == 2 and not _looks_numeric(cells[0]) and not _looks_numeric(cells[1]):
                raise ValueError(f"{where}: header {','.join(cells)!r} is not allowed; "
                                 f"expected '{','.join(CSV_HEADER)}' or no header")
        if len(cells) != 2:
            raise ValueError(f"{where}: expected 2 columns (time_s, omega_rpm), got {len(cells)}: {','.join(row)!r}")
        t = _as_number(cells[0], "time_s", where)
        w = _as_number(cells[1], "omega_rpm", where)
        steps.append((t, w))
        labels.append(where)
    if not steps:
        raise ValueError(f"{name}: no schedule rows found; expected lines 'time_s,omega_rpm'")
    return steps, labels


def _looks_numeric(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _parse_json(text: str, name: str) -> tuple[list[tuple[float, float]], list[str]]:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{name}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    key = "entry"
    if isinstance(data, dict):
        if set(data) != {"steps"}:
            raise ValueError(f"{name}: JSON object keys {sorted(data)} are not allowed; expected only 'steps'")
        data, key = data["steps"], "steps"
    if not isinstance(data, list) or not data:
        raise ValueError(f"{name}: expected a non-empty list [[time_s, omega_rpm], ...], got {type(data).__name__}")
    steps: list[tuple[float, float]] = []
    labels: list[str] = []
    for i, item in enumerate(data):
        where = f"{name}: {key}[{i}]"
        if not isinstance(item, list) or len(item) != 2:
            raise ValueError(f"{where}: {item!r} is not allowed; expected a pair [time_s, omega_rpm]")
        for value, what in zip(item, CSV_HEADER):
            if isinstance(value, bool) or not isinstance(value, Real):
                raise ValueError(f"{where}: {what}={value!r} is not a number")
        steps.append((float(item[0]), float(item[1])))
        labels.append(where)
    return steps, labels

