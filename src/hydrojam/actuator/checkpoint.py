"""A run's resumable state on disk: ``checkpoint.npz`` in its output folder, rewritten
(atomically) after every accepted load step and every round of the release, so that a run
stopped by a crash, a kill or the end of a session goes on from its last accepted state
(docs/actuator.md, "Checkpoints").

The file holds plain data only (arrays and one JSON text, read without pickle): the accepted
states so far (their metrics and positions), the load path's state (:class:`PathCheckpoint`)
and, once the release has begun, the release's. It names its design by a digest of the resolved
design, and is ignored for any other design.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hydrojam._io import atomic_path
from hydrojam.fem import PathCheckpoint, StepRecord, Timings

#: the checkpoint's file name in a run's output folder
CHECKPOINT = "checkpoint.npz"

#: the file's layout; another one is ignored (a run then starts from s = 0). 2: the path's
#: states are equilibria (released at every step) and it keeps the state before the last one
FORMAT = 2


class CheckpointError(ValueError):
    """A checkpoint that cannot be resumed: unreadable, another format, design or mesh."""


@dataclass(frozen=True)
class ReleaseCheckpoint:
    """The release at s = 1 between two rounds: positions x (n, d) [mm] of the next round's
    centre (the last converged round's state, or a failed round's kept beyond the damping's
    cap), Newton iterations so far, the damping scale of the next round (absolute, the term's
    ``scale``), whether a round has failed since the damping was last lowered, and the rounds so
    far as (scale, iterations, converged)."""

    x: np.ndarray
    iterations: int
    scale: float
    failed: bool
    rounds: tuple[tuple[float, int, bool], ...]
    seconds: float = 0.0
    """Wall time spent in the release so far [s]."""
    solver_pattern: tuple[np.ndarray, np.ndarray] | None = None
    """The release's linear solver's union pattern (as :attr:`PathCheckpoint.solver_pattern`)."""
    timings: Timings | None = None
    """The release's Newton work so far (its rounds' and direct attempt's :class:`Timings`, failed
    ones included); None in a checkpoint written before it was kept."""


@dataclass(frozen=True)
class ReleaseProgress:
    """How far a run's release at s = 1 has gone: the rounds so far, their Newton iterations (failed
    rounds included), the next round's damping as a multiple of the design's [-] and the release's
    wall time so far [s]."""

    rounds: int
    iterations: int
    damping: float
    seconds: float

    def summary(self) -> str:
        """The rounds, iterations and damping in a few words ("12 rounds, 1534 iterations, damping 100x")."""
        return (f"{self.rounds} round{'' if self.rounds == 1 else 's'}, {self.iterations} iterations, "
                f"damping {self.damping:.3g}x")


def release_progress(path: str | Path) -> ReleaseProgress | None:
    """The release's progress recorded in the checkpoint at ``path`` (read without its arrays:
    cheap while the run goes on, for any design); None where there is no checkpoint, it cannot be
    read or its run has not begun the release."""
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
        r = meta["release"]
        return None if r is None else ReleaseProgress(len(r["rounds"]), int(r["iterations"]), float(r["scale"]),
                                                   float(r["seconds"]))
    except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile, EOFError):
        return None


@dataclass(frozen=True)
class RunCheckpoint:
    """A run stopped after an accepted state.

    Parameters
    ----------
    design_digest : str
        The digest of the design it was written for.
    states : tuple of dict
        The accepted states as plain dicts (:class:`~hydrojam.actuator.simulate.StepState`'s
        fields but x).
    xs : ndarray, shape (k, n, d)
        Their positions [mm].
    path : PathCheckpoint
        The load path's state.
    release : ReleaseCheckpoint or None
        The release's state, None before it began.
    elapsed_s : float
        The run's wall time before it stopped [s].
    clocks : dict
        Seconds spent in elastic and contact terms [s].
    energy_ratio : float
        The stabilisation's largest energy ratio so far [-].
    resumed : tuple of dict, optional
        One record per earlier resumption (s and state index it went on from, version).
    """

    design_digest: str
    states: tuple[dict, ...]
    xs: np.ndarray
    path: PathCheckpoint
    release: ReleaseCheckpoint | None
    elapsed_s: float
    clocks: dict
    energy_ratio: float
    resumed: tuple[dict, ...] = ()


def design_digest(design) -> str:
    """A digest of the resolved design (pydantic's JSON of every field): equal for equal designs."""
    return hashlib.sha256(design.model_dump_json().encode()).hexdigest()


def _plain(value):
    """numpy scalars as Python numbers in the JSON text."""
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def save_checkpoint(path: str | Path, ck: RunCheckpoint) -> None:
    """Write a checkpoint atomically (a reader never sees half a file).

    Parameters
    ----------
    path : str or Path
        The file to write.
    ck : RunCheckpoint
        The checkpoint.
    """
    meta = {
        "format": FORMAT,
        "design_digest": ck.design_digest,
        "states": list(ck.states),
        "path": {"s": ck.path.s, "ds": ck.path.ds, "damping": ck.path.damping, "rejected": ck.path.rejected,
                 "ds_cut": ck.path.ds_cut, "history": [dataclasses.asdict(h) for h in ck.path.history],
                 "timings": dataclasses.asdict(ck.path.timings)},
        "release": None if ck.release is None else {
            "iterations": ck.release.iterations, "scale": ck.release.scale, "failed": ck.release.failed,
            "rounds": [list(r) for r in ck.release.rounds], "seconds": ck.release.seconds,
            "timings": None if ck.release.timings is None else dataclasses.asdict(ck.release.timings)},
        "elapsed_s": ck.elapsed_s,
        "clocks": ck.clocks,
        "energy_ratio": ck.energy_ratio,
        "resumed": list(ck.resumed),
    }
    if ck.path.previous is not None:
        meta["path"]["previous_ds"] = float(ck.path.previous[1])
    arrays = {"meta": np.array(json.dumps(meta, default=_plain)), "xs": np.asarray(ck.xs, dtype=float),
              "path_x": np.asarray(ck.path.x, dtype=float)}
    if ck.release is not None:
        arrays["release_x"] = np.asarray(ck.release.x, dtype=float)
    if ck.path.previous is not None:
        arrays["path_previous_x"] = np.asarray(ck.path.previous[0], dtype=float)
    for name, pattern in (("path", ck.path.solver_pattern),
                          ("release", None if ck.release is None else ck.release.solver_pattern)):
        if pattern is not None:
            arrays[f"{name}_indptr"], arrays[f"{name}_indices"] = (np.asarray(a, dtype=np.int32) for a in pattern)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)


def load_checkpoint(path: str | Path, design, shape: tuple[int, int]) -> RunCheckpoint:
    """The checkpoint at ``path`` for ``design``.

    Parameters
    ----------
    path : str or Path
        The checkpoint file.
    design : Design
        The design it must have been written for.
    shape : tuple of int
        (nodes, dimension) of the positions, those of the design's mesh.

    Returns
    -------
    RunCheckpoint

    Raises
    ------
    FileNotFoundError
        Where there is none.
    CheckpointError
        Saying why, for one that cannot be resumed.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            xs, path_x = data["xs"], data["path_x"]
            release_x = data["release_x"] if "release_x" in data else None
            previous_x = data["path_previous_x"] if "path_previous_x" in data else None
            patterns = {name: (data[f"{name}_indptr"], data[f"{name}_indices"]) if f"{name}_indptr" in data else None
                        for name in ("path", "release")}
    except FileNotFoundError:
        raise
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as err:
        raise CheckpointError(f"{path}: unreadable ({' '.join(str(err).split())})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise CheckpointError(f"{path}: written in another format")
    if meta.get("design_digest") != design_digest(design):
        raise CheckpointError(f"{path}: written for another design")
    shape = tuple(shape)
    release_fits = release_x is None or release_x.shape == shape
    if xs.shape[1:] != shape or len(xs) != len(meta["states"]) or not len(xs) or path_x.size != xs[0].size \
            or not release_fits:
        raise CheckpointError(f"{path}: its positions do not fit this design's mesh ({shape[0]} nodes)")
    if not (np.all(np.isfinite(xs)) and np.all(np.isfinite(path_x))
            and (release_x is None or np.all(np.isfinite(release_x)))):
        raise CheckpointError(f"{path}: non-finite positions")
    p = meta["path"]
    path_ck = PathCheckpoint(path_x, float(p["s"]), float(p["ds"]), float(p["damping"]),
                             tuple(StepRecord(**h) for h in p["history"]), int(p["rejected"]),
                             Timings(**p["timings"]), patterns["path"],
                             None if p.get("ds_cut") is None else float(p["ds_cut"]),
                             None if previous_x is None or previous_x.size != path_x.size
                             else (previous_x, float(p["previous_ds"])))
    r = meta["release"]
    release = None if r is None else ReleaseCheckpoint(
        release_x, int(r["iterations"]), float(r["scale"]), bool(r["failed"]),
        tuple((float(a), int(b), bool(c)) for a, b, c in r["rounds"]), float(r["seconds"]), patterns["release"],
        None if r.get("timings") is None else Timings(**r["timings"]))
    return RunCheckpoint(meta["design_digest"], tuple(meta["states"]), xs, path_ck, release,
                         float(meta["elapsed_s"]), dict(meta["clocks"]), float(meta["energy_ratio"]),
                         tuple(meta["resumed"]))


__all__ = ["CHECKPOINT", "CheckpointError", "ReleaseCheckpoint", "ReleaseProgress", "RunCheckpoint", "design_digest",
           "load_checkpoint", "release_progress", "save_checkpoint"]
