"""The design map (docs/assess.md): bending angle, stiffness ratio and confinement over
the membrane's wall thickness and shear modulus, run as a study sweep (:mod:`hydrojam.study`:
parallel, cached, resumable), one assessment without blocked force and baselines per point."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from hydrojam._io import atomic_path, write_text_atomic
from hydrojam.actuator.design import Design
from hydrojam.assess.assessment import assess, check_assessable
from hydrojam.assess.spec import Loads
from hydrojam.study.spec import Study, SweepSpec
from hydrojam.study.sweep import run_sweep

THICKNESS, MODULUS = "side_wall_thickness", "membrane.shear_modulus"
#: what a point of the map records (besides the sweep's own columns)
MAP_VALUES = ("bending_angle_deg", "stiffness_ratio", "contact_pressure_mean", "contact_pressure_max",
              "swelling_pressure", "confinement_share", "converged")


def map_point(design: Design, point_dir: Path) -> dict:
    """One point of the map: the design's assessment without blocked force and baselines; its values
    (:data:`MAP_VALUES`; ``confinement_share`` = mean contact pressure / confined swelling
    pressure) also written to ``point_dir``/assessment.json."""
    a = assess(design, Loads(blocking=False, vacuum=False, pneumatic=False))
    v = a.values
    values = {k: v[k] for k in ("bending_angle_deg", "stiffness_ratio", "contact_pressure_mean",
                                "contact_pressure_max", "swelling_pressure")}
    values["confinement_share"] = v["contact_pressure_mean"] / v["swelling_pressure"] if v["swelling_pressure"] > 0 else None
    values["converged"] = bool(v["actuation_converged"] and all(c.converged for c in a.curves.values()))
    values["wall_time_s"] = v["wall_time_s"]
    write_text_atomic(Path(point_dir) / "assessment.json", json.dumps(a.summary(), indent=1, allow_nan=False) + "\n")
    return values


def map_study(base: Design, thicknesses, shear_moduli) -> Study:
    """The study of the map: one sweep "membrane" over ``thicknesses`` [mm] (side_wall_thickness)
    x ``shear_moduli`` [MPa] (membrane.shear_modulus). Every point's design is validated here:
    DesignError naming the field, the value and its allowed range for the first that is not a
    valid design (a modulus above the field's range, a wall too thin for the mesh)."""
    from pydantic import ValidationError

    from hydrojam.study.spec import StudyError, validation_message

    try:
        return Study(name="design_map", base=base, sweeps=[SweepSpec(
            name="membrane", vary={THICKNESS: [float(t) for t in thicknesses],
                                   MODULUS: [float(g) for g in shear_moduli]})])
    except ValidationError as err:
        raise StudyError(validation_message(err, Study, "")) from None


def design_map(base: Design, thicknesses, shear_moduli, out: str | os.PathLike, workers: int | None = None,
               on_point=None) -> list[dict]:
    """Run the map over ``thicknesses`` [mm] (the membrane's side walls, t0) x ``shear_moduli``
    [MPa] (the membrane's G; Ecoflex 00-30 0.023, Dragon Skin 30-class about 0.2) from ``base``
    into ``out`` (a study folder: cached and resumable). Returns one row per point: t0, G and
    :data:`MAP_VALUES` (None where a point failed), and writes ``out``/design_map.png. Raises
    DesignError for a base design that cannot be assessed (a 3D one), before anything runs."""
    check_assessable(base)
    study = map_study(base, thicknesses, shear_moduli)
    run_sweep(study, out, workers=workers, on_point=on_point, point_fn=map_point)
    rows = []
    for p in study.points():
        record = Path(out) / "points" / p.key / "point.json"
        metrics = (json.loads(record.read_text()).get("metrics") or {}) if record.exists() else {}
        rows.append({THICKNESS: p.values[THICKNESS], MODULUS: p.values[MODULUS],
                     **{k: metrics.get(k) for k in MAP_VALUES}})
    plot_design_map(rows, Path(out) / "design_map.png")
    return rows


def plot_design_map(rows: list[dict], path: str | os.PathLike) -> None:
    """Three panels over (t0, G): bending angle [deg], stiffness ratio [-] and the confinement
    share (mean contact pressure / confined swelling pressure, log10)."""
    ts = sorted({r[THICKNESS] for r in rows})
    gs = sorted({r[MODULUS] for r in rows})
    fig = Figure(figsize=(13, 4))
    panels = (("bending_angle_deg", "bending angle [deg]", False), ("stiffness_ratio", "stiffness ratio [-]", False),
              ("confinement_share", "log10(contact / swelling pressure)", True))
    for i, (key, title, log) in enumerate(panels):
        ax = fig.add_subplot(1, 3, i + 1)
        grid = np.full((len(gs), len(ts)), np.nan)
        for r in rows:
            value = r.get(key)
            if value is not None and (not log or value > 0):
                grid[gs.index(r[MODULUS]), ts.index(r[THICKNESS])] = np.log10(value) if log else value
        im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis")
        ax.set_xticks(range(len(ts)), [f"{t:g}" for t in ts])
        ax.set_yticks(range(len(gs)), [f"{g:g}" for g in gs])
        ax.set_xlabel("membrane wall thickness t0 [mm]")
        ax.set_ylabel("membrane shear modulus G [MPa]")
        ax.set_title(title)
        for (gi, ti), value in np.ndenumerate(grid):
            if np.isfinite(value):
                ax.text(ti, gi, f"{value:.2g}", ha="center", va="center", color="w", fontsize=8)
        fig.colorbar(im, ax=ax)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
