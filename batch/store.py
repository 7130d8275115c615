"""A sweep's output directory: ``results.jsonl`` written point by point, trajectories beside it.

Each finished point is one JSON line, appended with a single write and fsync'ed before the
next point is handled, so a crash or kill loses at most the points still running. A line
cut short by a crash (the file's last line) is dropped when the sweep resumes. When one point
has several lines (a retried failure), the last one counts.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

try:
    import fcntl
except ImportError:  # Windows: no lock, the rest works
    fcntl = None  # type: ignore[assignment]

RESULTS_FILE = "results.jsonl"
POINTS_DIR = "points"
LOCK_FILE = ".sweep.lock"


class SweepError(RuntimeError):
    """A sweep cannot start or did not finish; the message says what to do."""


def read_results(path: Path) -> tuple[dict[str, dict[str, Any]], int, bool]:
    """Records of ``path`` by point id (last line wins), plus how to repair the file's end.

    Returns ``(records, good_bytes, needs_newline)``: bytes after ``good_bytes`` are a torn
    last line; ``needs_newline`` when the last record lacks its line end. SweepError names a
    damaged line that is not the last.
    """
    if not path.exists():
        return {}, 0, False
    data = path.read_bytes()
    records: dict[str, dict[str, Any]] = {}
    start, number = 0, 0
    while start < len(data):
        end = data.find(b"\n", start)
        last = end < 0
        chunk = data[start:] if last else data[start:end]
        number += 1
        record = _parse(chunk)
        if record is None and chunk.strip():
            if last:  # torn by a crash while writing; drop it
                return records, start, False
            raise SweepError(f"{path} line {number} is not a sweep record; fix or delete that line, "
                             "then run again")
        if record is not None:
            records[record["point_id"]] = record
        if last:
            return records, len(data), record is not None
        start = end + 1
    return records, len(data), False


def _parse(chunk: bytes) -> dict[str, Any] | None:
    try:
        record = json.loads(chunk)
    except (ValueError, UnicodeDecodeError):
        return None
    if isinstance(record, dict) and isinstance(record.get("point_id"), str):
        return record
    return None


def _json_safe(value: Any) -> Any:
    """Non-finite floats -> None, recursively (strict JSON)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


class ResultsStore:
    """``out_dir`` opened for a sweep (use as a context manager); locked against a second sweep.

    Without ``resume``, a non-empty ``results.jsonl`` is a SweepError. ``records`` holds the
    results already there, by point id.
    """

    def __init__(self, out_dir: str | os.PathLike[str], resume: bool) -> None:
        self.out_dir = Path(out_dir)
        self.path = self.out_dir / RESULTS_FILE
        self.points_dir = self.out_dir / POINTS_DIR
        self.resume = resume
        self.records: dict[str, dict[str, Any]] = {}
        self._fd: int | None = None
        self._lock_fd: int | None = None

    def __enter__(self) -> ResultsStore:
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise SweepError(f"cannot create the output directory {str(self.out_dir)!r} ({exc.strerror})") from None
        self._lock()
        try:
            if not self.resume and self.path.exists() and self.path.stat().st_size > 0:
                n = len(read_results(self.path)[0])
                raise SweepError(f"{self.path} already holds {n} result{'s' if n != 1 else ''}; pass --resume "
                                 "(resume=True) to continue that sweep, or choose another --out directory")
            self.records, good, needs_newline = read_results(self.path)
            self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
            if good < os.fstat(self._fd).st_size:
                os.truncate(self.path, good)
            if needs_newline:
                self._write(b"\n")
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if self._lock_fd is not None:
            os.close(self._lock_fd)  # releases the flock
            self._lock_fd = None

    def reload(self) -> dict[str, dict[str, Any]]:
        """Re-read ``records`` from the file (after an interrupt, the file is what counts)."""
        self.records = read_results(self.path)[0]
        return self.records

    def append(self, record: dict[str, Any], trajectory: Any | None = None) -> dict[str, Any]:
        """Save the trajectory (if any), then the record as one fsync'ed line; returns the record."""
        record = _json_safe(dict(record))
        if trajectory is not None:
            record["trajectory"] = self._save_trajectory(record["point_id"], trajectory)
        line = json.dumps(record, allow_nan=False, separators=(",", ":")) + "\n"
        self._write(line.encode("utf-8"))
        self.records[record["point_id"]] = record
        return record

    def _save_trajectory(self, pid: str, trajectory: Any) -> str:
        """``points/<pid>.npz`` written under a temporary name first; returns the path relative to out_dir."""
        self.points_dir.mkdir(exist_ok=True)
        final = self.points_dir / f"{pid}.npz"
        tmp = self.points_dir / f"{pid}.partial.npz"
        trajectory.save_npz(tmp)
        os.replace(tmp, final)
        return f"{POINTS_DIR}/{pid}.npz"

    def _write(self, data: bytes) -> None:
        assert self._fd is not None, "ResultsStore used outside 'with'"
        view = memoryview(data)
        while view:
            view = view[os.write(self._fd, view):]
        os.fsync(self._fd)

    def _lock(self) -> None:
        self._lock_fd = os.open(self.out_dir / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
        if fcntl is None:
            return
        try:
            fcntl.flock(self._lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self._lock_fd)
            self._lock_fd = None
            raise SweepError(f"another sweep is writing to {self.out_dir}; wait for it to end or choose "
                             "another --out directory") from None


# --- the run a folder holds ------------------------------------------------------------
def drop_rows_after(file: Path, column: str, last: int, fields: Sequence[str]) -> None:
    """Rewrite the CSV ``file`` (header ``fields``) without the rows whose ``column`` is above ``last``: what a killed
    run logged after the checkpoint it resumes from (redone, so kept once). A missing file or value is left alone."""
    if not file.is_file():
        return
    with open(file, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))

    def number(row: dict[str, str]) -> float:
        try:
            return float(row.get(column) or 0)
        except ValueError:
            return 0.0

    keep = [r for r in rows if number(r) <= last]
    if len(keep) == len(rows):
        return
    tmp = file.with_name(file.name + ".tmp")
    with open(tmp, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=list(fields))
        w.writeheader()
        w.writerows(keep)
    shutil.move(str(tmp), str(file))


def first_difference(old: Any, new: Any, prefix: str = "") -> tuple[str, Any, Any] | None:
    """``(key path, old value, new value)`` of the first setting that differs between two JSON-like documents
    (dicts compared key by key, in sorted order), or None when they are equal."""
    if isinstance(old, dict) and isinstance(new, dict):
        for key in sorted(set(old) | set(new), key=str):
            path = f"{prefix}.{key}" if prefix else str(key)
            if key not in old or key not in new:
                return path, old.get(key, _ABSENT), new.get(key, _ABSENT)
            diff = first_difference(old[key], new[key], path)
            if diff is not None:
                return diff
        return None
    return None if old == new else (prefix or "(the whole document)", old, new)


def check_same_run(folder: Path, file_name: str, identity: dict[str, Any], what: str) -> None:
    """Refuse (SweepError, one line naming the first difference) to resume in ``folder`` when its ``file_name``
    (JSON: its key ``"run"``, else its keys named in ``identity``) describes another run than ``identity``. A folder
    without the file passes (the caller checks its records)."""
    file = Path(folder) / file_name
    if not file.is_file():
        return
    try:
        doc = json.loads(file.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise SweepError(f"{file} cannot be read ({exc}); it says which run {folder} holds: fix or delete it") from None
    new = json.loads(json.dumps(identity, default=str))  # tuples -> lists, as stored
    if not isinstance(doc, dict):
        raise SweepError(f"{file} is not a JSON object; it says which run {folder} holds: fix or delete it")
    old = doc["run"] if "run" in doc else {k: doc[k] for k in new if k in doc}
    diff = first_difference(old, new)
    if diff is not None:
        key, a, b = diff
        raise SweepError(f"--resume: {folder} holds another {what}: {key} is {short_repr(a)} there and {short_repr(b)} here; "
                         f"allowed: the same settings as that run, or another output folder")


def check_records_belong(records: dict[str, dict[str, Any]], ids: set[str], folder: Path, what: str) -> None:
    """Refuse (SweepError) when ``records`` hold results that are not among ``ids`` (another run's)."""
    foreign = [pid for pid in records if pid not in ids]
    if foreign:
        raise SweepError(f"--resume: {folder} holds {len(foreign)} result{'s' if len(foreign) != 1 else ''} of another "
                         f"{what} (e.g. point {foreign[0]}); allowed: the same settings as that run, or another "
                         "output folder")


class _Absent:
    def __repr__(self) -> str:
        return "(absent)"


_ABSENT = _Absent()


def short_repr(value: Any) -> str:
    """A value as a config file shows it (JSON, or repr for a string), cut to 80 characters: for one-line errors."""
    if value is _ABSENT:
        return "(absent)"
    s = json.dumps(value, default=str) if not isinstance(value, str) else repr(value)
    return s if len(s) <= 80 else s[:77] + "..."
