"""Keep a study's finished points as small records in the repository (the outcome, not the state).

Usage: python docs/data/keep.py OUT DEST

For every point of the study in OUT (OUT/study.toml) whose OUT/points/<key>/point.json says "ok"
or "not_converged", copy point.json, metrics.json, history.csv, centreline.csv and design.toml
into DEST/<label>-<key>/, OUT/study.toml into DEST/, and a ``restore.sh`` (:data:`RESTORE`, which runs
docs/data/restore.sh on DEST) into DEST/. The label names the point's first sweep
and value (T285, H4, W12, PL07) and, past replica 0, the replica (T285r2). Large files
(final.vtu, final.png, checkpoint.npz) are left out. ``restore.sh`` beside the records puts them
back into a study folder, where the sweep loads them instead of running them again.
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

from hydrojam.study.spec import load_study

#: DEST/restore.sh: docs/data/restore.sh on the records beside it
RESTORE = """#!/bin/sh
# Put this folder's kept records back into a study folder OUT: restore.sh OUT (docs/data/restore.sh).
here=$(cd "$(dirname "$0")" && pwd)
exec sh "$here/../restore.sh" --records "$here" "$@"
"""

FILES = ("point.json", "metrics.json", "history.csv", "centreline.csv", "design.toml")
PREFIX = {"stimulus.temperature": "T", "particle_layers": "PL", "strain_limit_thickness": "H",
          "strain_limit_width": "W"}


def label(point) -> str:
    """T285, PL07, H4, W12 (r<k> appended past replica 0)."""
    ((field, value),) = point.values.items()
    prefix = PREFIX.get(field, field.rsplit(".", 1)[-1])
    text = f"{prefix}{value:02d}" if prefix == "PL" else f"{prefix}{value:g}"
    return text + (f"r{point.replica}" if point.replica else "")


def keep(out: Path, dest: Path) -> list[str]:
    """Copy the finished points' records of the study in ``out`` into ``dest``; the names kept."""
    study = load_study(out / "study.toml")
    dest.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(out / "study.toml", dest / "study.toml")
    (dest / "restore.sh").write_text(RESTORE, encoding="utf-8")
    kept, seen = [], set()
    for point in study.points():
        src = out / "points" / point.key
        if point.key in seen or not (src / "point.json").is_file():
            continue
        seen.add(point.key)
        if json.loads((src / "point.json").read_text()).get("status") not in ("ok", "not_converged"):
            continue
        target = dest / f"{label(point)}-{point.key}"
        target.mkdir(exist_ok=True)
        for name in FILES:
            if (src / name).is_file():
                shutil.copyfile(src / name, target / name)
        trim_record(target)
        kept.append(target.name)
    return kept


def trim_record(folder: Path) -> None:
    """Make ``folder``/point.json list only the result files kept beside it (their checksums
    unchanged): the large files left out are then not missing from a restored point, and the
    sweep loads it instead of computing it again (hydrojam.study.cache.damaged_files)."""
    path = folder / "point.json"
    record = json.loads(path.read_text(encoding="utf-8"))
    files = record.get("files")
    if isinstance(files, dict):
        record["files"] = {k: v for k, v in files.items() if (folder / k).is_file()}
        path.write_text(json.dumps(record, indent=2, allow_nan=False) + "\n", encoding="utf-8")


if __name__ == "__main__":
    if len(sys.argv) == 2 and sys.argv[1] == "--trim-all":  # the records kept before trim_record
        for rec in sorted(Path(__file__).resolve().parent.glob("*/*/point.json")):
            trim_record(rec.parent)
        sys.exit(0)
    if len(sys.argv) != 3:
        sys.exit("usage: python docs/data/keep.py OUT DEST | --trim-all")
    names = keep(Path(sys.argv[1]), Path(sys.argv[2]))
    print(f"kept {len(names)} points in {sys.argv[2]}: {' '.join(names)}")
