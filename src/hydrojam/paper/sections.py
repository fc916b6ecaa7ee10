"""The paper study's results written into documentation pages: the tables of docs/reproduce.md
and the README are the command's output, not copies.

A page holds a section between ``<!-- reproduce: NAME -->`` and ``<!-- /reproduce: NAME -->``,
NAME the study's name (``paper-quick``, ``paper-3d-quick``, ...) for the table of its points, the
name followed by `` verdicts`` for the count of its verdicts, or by `` time`` for what its runs
cost. :func:`write_sections` replaces every such section of the study on a page (the table with a
line of conditions: command, commits, mesh, runs a point, friction, workers) and leaves the rest
of the page as it was. The section ``KIND sensitivity`` (KIND the study's name without its model
choices, ``paper-3d-quick``) is a table of verdict against model choice, a row per study of that
kind: :func:`write_sensitivity_row` replaces the row of one study (``default`` or its ``--set``
choices) and keeps the others'. The section ``NAME figures`` shows the study's trend figures:
:func:`write_figure_section` copies them beside the page (``_static/NAME/``) and links them.
Units: K, mm, degrees, minutes.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from collections.abc import Sequence
from pathlib import Path

from hydrojam._io import atomic_path, write_text_atomic
from hydrojam.actuator.design import Design
from hydrojam.actuator.provenance import source_provenance
from hydrojam.paper._rows import (cell, cell_pm, fmt_param, number, point_status, rows_of, sorted_by,
                                  without_result)
from hydrojam.paper.claims import PAPER_CLAIMS, ClaimResult, Verdict, check_state_claims
from hydrojam.paper.study import VARIANT_SEPARATOR, paper_sweeps, reproduce_command, study_name
from hydrojam.study.cache import PointStatus

__all__ = ["SECTION_KINDS", "SectionError", "check_page", "compare_lines", "results_lines", "run_commits",
           "sensitivity_row", "time_lines", "verdict_lines", "write_figure_section", "write_sections",
           "write_sensitivity_row"]

#: the sections a study can write on a page: "" (its points), " verdicts", " time", " compare"
#: (a 3D study against its 2D peer)
SECTION_KINDS = ("", " verdicts", " time", " compare")
#: the section of verdict against model choice, after the study's kind ("paper-3d-quick sensitivity")
SENSITIVITY = " sensitivity"
#: the section of a study's trend figures, after its name ("paper-3d-quick figures")
FIGURES = " figures"
#: the first cell of the row of the study under the default model choices
DEFAULT_CHOICE = "default"


class SectionError(ValueError):
    """A page that cannot take the study's results: missing, or without a marked section."""


def _begin(name: str) -> str:
    return f"<!-- reproduce: {name} -->"


def _end(name: str) -> str:
    return f"<!-- /reproduce: {name} -->"


def _section(name: str) -> re.Pattern:
    """The section ``name`` of a page, its markers included; group 1 its body."""
    return re.compile(re.escape(_begin(name)) + r"\n(.*?)" + re.escape(_end(name)), re.S)


def conditions_line(base: Design, quick: bool, replicas: int, workers: int | None, runs: tuple[int, int],
                    run_commits: tuple[str, ...] = (), overrides: Sequence[str] = ()) -> str:
    """One line of conditions: the command, the commits of the code that computed the runs (else
    the code writing the table), mesh, runs a point, friction, workers, and how many of the
    study's runs have finished."""
    src = source_provenance()
    commit = ", ".join(f"`{c[:7]}`" for c in run_commits) if run_commits else \
        f"`{str(src.get('commit') or 'unknown')[:7]}`" + (" (with local changes)" if src.get("dirty") is True else "")
    dim = base.dimension
    model = "3D half model" if dim == 3 and base.mesh.symmetry else ("3D" if dim == 3 else "2D plane strain")
    friction = "frictionless" if base.friction == 0 else f"friction {base.friction:g}"
    who = f"{workers} workers" if workers else "one worker per CPU"
    return (f"Conditions: `{reproduce_command(quick, dim, replicas, overrides)}`, runs computed by the code of {commit}, {model}, mesh "
            f"{base.mesh_size:g} mm, {replicas} run{'s' if replicas != 1 else ''} a point, {friction}, {who} on "
            f"{os.cpu_count()} cores; {runs[0]} of {runs[1]} runs finished. θ, δx, δz: mean ± standard deviation "
            "over the runs that converged; the states as in docs/replicas.md.")


def run_commits(study, out: str | os.PathLike) -> tuple[str, ...]:
    """The commits of the code that computed the finished runs of ``study`` in ``out``, sorted:
    read from each run's metrics.json (``provenance.source.commit``), those without one left out."""
    commits = set()
    for key in {p.key for p in study.points()}:
        try:
            data = json.loads((Path(out) / "points" / key / "metrics.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        commit = ((data.get("provenance") or {}).get("source") or {}).get("commit")
        if isinstance(commit, str) and re.fullmatch(r"[0-9a-f]{7,40}", commit):
            commits.add(commit)
    return tuple(sorted(commits))


def _distinct_points(table, dimension: int) -> dict:
    """Design key -> the first row of each distinct point of the study's sweeps (the base point
    stands in several)."""
    rows = {}
    for sw in paper_sweeps(dimension):
        for r in rows_of(table, sw.name):
            rows.setdefault(r.get("key"), r)
    return rows


def _finished_runs(row: dict, replicas: int) -> int:
    """How many runs of a point finished: its replicas used, or 1 for a single run that did."""
    if replicas > 1:
        return int(number(row.get("replicas_used")) or 0)
    return int(point_status(row) in (PointStatus.OK, PointStatus.NOT_CONVERGED))


def _state_cell(row: dict, states: dict) -> str:
    """A point's states with θ in each: "arc 1: 168.3; folded 2: 101.9 ± 0.7" (one state: its name)."""
    parts = []
    for name, table in states.items():
        mine = [r for r in rows_of(table, row.get("sweep")) if r.get("point") == row.get("point")]
        if not mine or without_result(mine[0]):  # a point with runs in the state, others to finish, counts
            continue
        n = int(number(mine[0].get("replicas_used")) or 1)
        parts.append((name, n, cell_pm(mine[0], "bending_angle_deg")))
    if len(parts) <= 1:
        return parts[0][0] if parts else "—"
    return "; ".join(f"{name} {n}: {theta}" for name, n, theta in parts)


def results_lines(table, base: Design, quick: bool, replicas: int, workers: int | None, states: dict,
                  results: list[ClaimResult], run_commits: tuple[str, ...] = (),
                  overrides: Sequence[str] = ()) -> list[str]:
    """The table of a study's points (Markdown) with its conditions line and its verdicts.

    Parameters
    ----------
    table : SweepTable
        The study's results.
    base : Design
        The study's base design.
    quick : bool
        The quick study.
    replicas : int
        Runs a point.
    workers : int or None
        Local workers.
    states : dict of str to SweepTable
        State -> the table of its runs alone (:func:`hydrojam.study.table.state_tables`).
    results : list of ClaimResult
        The claims checked on ``table``.
    run_commits : tuple of str, optional
        The commits of the code that computed the finished runs (their metrics' provenance).
    overrides : sequence of str, optional
        The study's model choices (``--set``).

    Returns
    -------
    list of str
    """
    dim = base.dimension
    sweeps = paper_sweeps(dim)
    rows = [r for sw in sweeps for r in rows_of(table, sw.name)]
    dirs = {d for r in rows for d in str(r.get("replica_dirs") or r.get("point_dir") or "").split(";") if d}
    finished = {key: _finished_runs(r, replicas) for key, r in _distinct_points(table, dim).items()}
    L = [conditions_line(base, quick, replicas, workers, (sum(finished.values()), len(dirs)), run_commits,
                         overrides), "",
         "| sweep | point | θ [deg] | δx [mm] | δz [mm] | curling index | runs | states (runs: θ [deg]) | "
         "Newton iterations (mean) | compute [min] |",
         "|---|---:|---:|---:|---:|---:|---:|---|---:|---:|"]
    for sw in sweeps:
        for r in sorted_by(rows_of(table, sw.name), sw.field):
            status = point_status(r)
            value = fmt_param(number(r.get(sw.field)), sw.unit)
            if status in (PointStatus.FAILED, PointStatus.UNFINISHED) and not number(r.get("bending_angle_deg")):
                L.append(f"| {sw.name} | {value} | {status} | | | | 0/{r.get('replicas') or 1} | | | |")
                continue
            used = f"{cell(r.get('replicas_used'), '{:.0f}')}/{cell(r.get('replicas'), '{:.0f}')}" \
                if replicas > 1 else "1/1"
            wall = number(r.get("wall_time_s"))
            L.append(f"| {sw.name} | {value} | {cell_pm(r, 'bending_angle_deg')} | {cell_pm(r, 'tip_dx_mm')} | "
                     f"{cell_pm(r, 'tip_dz_mm')} | {cell_pm(r, 'curling_index', '{:.2f}')} | {used} | "
                     f"{_state_cell(r, states)} | {cell(r.get('newton_iterations'), '{:.0f}')} | "
                     f"{'' if wall is None else f'{wall / 60:.1f}'} |")
    L += [""] + verdict_lines(results, study_name(quick, dim, overrides))
    return L


def time_lines(table, base: Design, quick: bool, replicas: int, workers: int | None,
               run_commits: tuple[str, ...] = (), overrides: Sequence[str] = ()) -> list[str]:
    """What a study's finished runs cost, as a one-row Markdown table: runs finished, Newton
    iterations a run (the range of the points' means, and the mean), compute a run and in all.

    Parameters
    ----------
    table : SweepTable
        The study's results.
    base : Design
        The study's base design.
    quick : bool
        The quick study.
    replicas : int
        Runs a point.
    workers : int or None
        Local workers.
    run_commits : tuple of str, optional
        The commits of the code that computed the runs.
    overrides : sequence of str, optional
        The study's model choices (``--set``).

    Returns
    -------
    list of str
    """
    rows = _distinct_points(table, base.dimension)
    runs = iters = 0.0
    compute = 0.0
    means = []
    for r in rows.values():
        n = _finished_runs(r, replicas)
        it, wall = number(r.get("newton_iterations")), number(r.get("wall_time_s"))
        if not n or it is None:
            continue
        runs += n
        iters += it * n
        compute += wall or 0.0
        means.append(it)
    commit = ", ".join(f"`{c[:7]}`" for c in run_commits) or "—"
    span = f"{min(means):.0f}-{max(means):.0f} (mean {iters / runs:.0f})" if means else "—"
    per_run = f"{compute / runs / 60:.1f} min" if runs else "—"
    who = f"{workers} workers" if workers else "one worker per CPU"
    return [f"| study | runs finished | Newton iterations a run | compute a run | compute in all | conditions |",
            "|---|---:|---|---:|---:|---|",
            f"| `{reproduce_command(quick, base.dimension, replicas, overrides)}` | {runs:.0f} of "
            f"{sum(int(number(r.get('replicas')) or 1) for r in rows.values())} | {span} | {per_run} | "
            f"{compute / 3600:.1f} h | mesh {base.mesh_size:g} mm, {who} of one thread on {os.cpu_count()} cores, "
            f"code {commit} |"]


def verdict_lines(results: list[ClaimResult], name: str) -> list[str]:
    """The verdicts of a study as one Markdown table: each verdict with its count and claims."""
    L = [f"| {name} | claims |", "|---|---|"]
    for v in Verdict:
        ids = [c.claim.id for c in results if c.verdict == v]
        if ids:
            L.append(f"| {v} | {len(ids)}: {', '.join(ids)} |")
    return L


def check_page(page: str | os.PathLike, name: str) -> None:
    """SectionError unless ``page`` can be read and written and holds a section of study ``name``."""
    path = Path(page)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise SectionError(f"{path}: cannot be read ({err.strerror or err})") from None
    if not any(_begin(name + kind) in text for kind in SECTION_KINDS) and _begin(_kind(name) + SENSITIVITY) not in text:
        raise SectionError(f"{path}: no section {_begin(name)} ... {_end(name)} (nor '{name} verdicts', "
                           f"'{name} time', '{_kind(name)}{SENSITIVITY}') to write the results into")
    if not os.access(path.parent, os.W_OK) or not os.access(path, os.W_OK):
        raise SectionError(f"{path}: cannot be written (permission denied)")


def write_sections(page: str | os.PathLike, name: str, table_lines: list[str], verdicts: list[str],
                   time: list[str] | None = None, compare: list[str] | None = None) -> list[str]:
    """Replace the sections of study ``name`` on ``page`` (atomically): ``NAME`` gets
    ``table_lines``, ``NAME verdicts`` gets ``verdicts``, ``NAME time`` gets ``time``, ``NAME
    compare`` gets ``compare`` (a 3D study with its 2D peer: :func:`compare_lines`); a section
    whose lines are not given keeps its text.

    Parameters
    ----------
    page : str or os.PathLike
        A Markdown page.
    name : str
        The study's name.
    table_lines, verdicts : list of str
        The sections' new contents.
    time : list of str, optional
        The cost section's (:func:`time_lines`).
    compare : list of str, optional
        The 2D-against-3D section's (:func:`compare_lines`).

    Returns
    -------
    list of str
        The sections replaced.

    Raises
    ------
    SectionError
        The page cannot be read, or holds no section of the study.
    """
    path = Path(page)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise SectionError(f"{path}: cannot be read ({err.strerror or err})") from None
    written = []
    for section, lines in ((name, table_lines), (f"{name} verdicts", verdicts), (f"{name} time", time or []),
                           (f"{name} compare", compare)):
        pattern = _section(section)
        if lines is None:
            continue
        if pattern.search(text):
            body = "\n".join([_begin(section), *lines, _end(section)])
            text = pattern.sub(lambda _: body, text)
            written.append(section)
    if written:
        write_text_atomic(path, text)
    elif _begin(_kind(name) + SENSITIVITY) not in text:
        raise SectionError(f"{path}: no section {_begin(name)} ... {_end(name)} (nor '{name} verdicts', "
                           f"'{name} time') to write the results into")
    return written


def compare_lines(results_3d: list[ClaimResult], results_2d: list[ClaimResult], point_lines: list[str],
                  source: str) -> list[str]:
    """The section "2D against 3D" of a results page: each statement's verdict in 2D and in 3D
    side by side, which statements each mode alone reproduces, then the points' table
    (:func:`hydrojam.paper.compare.comparison_lines` without its heading).

    Parameters
    ----------
    results_3d, results_2d : list of ClaimResult
        The claims checked on the 3D study and on its 2D peer.
    point_lines : list of str
        The report's section "2D against 3D" (Markdown lines).
    source : str
        The 2D study's folder, as given.

    Returns
    -------
    list of str
    """
    two = {c.claim.id: c.verdict for c in results_2d}
    three = {c.claim.id: c.verdict for c in results_3d}
    ids = [cid for cid in _claim_ids(3) if cid in two or cid in three]
    L = ["| statement | 2D | 3D |", "|---|---|---|"]
    for cid in ids:
        L.append(f"| {cid} | {two.get(cid, '— (3D only)' if cid.startswith('hw-') else '—')} | {three.get(cid, '—')} |")
    only2 = [c for c in ids if two.get(c) == Verdict.AGREE and three.get(c) not in (None, Verdict.AGREE)]
    only3 = [c for c in ids if three.get(c) == Verdict.AGREE and two.get(c) not in (None, Verdict.AGREE)]
    both = [c for c in ids if two.get(c) == Verdict.AGREE and three.get(c) == Verdict.AGREE]
    L += ["", f"Both reproduce: {', '.join(both) or 'none'}. 2D alone: {', '.join(only2) or 'none'}. "
          f"3D alone: {', '.join(only3) or 'none'} (the 2D study in `{source}`).", ""]
    body = list(point_lines)
    while body and (not body[0].strip() or body[0].startswith("## ")):
        body.pop(0)
    return L + body


#: a claim's summary checked on part of the paper's range, and how a table cell says so
_PARTIAL_MARK, _PARTIAL = "checked on the points run", "part of the range"


def _kind(name: str) -> str:
    """The study's kind: its name without its model choices ("paper-3d-quick--friction_0_3" -> "paper-3d-quick")."""
    return name.split(VARIANT_SEPARATOR, 1)[0]


def _claim_ids(dimension: int) -> list[str]:
    """The claims of the sweeps a study of ``dimension`` runs, in the paper's order."""
    return [c.id for c in PAPER_CLAIMS if any(sw.name == c.sweep for sw in paper_sweeps(dimension))]


def _sensitivity_header(dimension: int) -> list[str]:
    ids = _claim_ids(dimension)
    return ["| model choice | runs | states | " + " | ".join(ids) + " | code |",
            "|---|---:|---|" + "---|" * len(ids) + "---|"]


def sensitivity_row(table, dimension: int, replicas: int, overrides: Sequence[str], states: dict,
                    results: list[ClaimResult], run_commits: tuple[str, ...] = ()) -> str:
    """One row of the table of verdict against model choice (Markdown): the study's choices
    (``default`` for none), its runs, each point's states, every claim's verdict on all runs, with
    each state's verdict beside it where the runs fall into more than one state and that state's
    runs decide one ("disagree; arc: agree"), and the code that computed the runs. A point is
    named by the paper's symbol, "hw" for the strip's width ("T 285 K: arc 2, folded 1"). A claim
    of a sweep the study did not run is "—".

    Parameters
    ----------
    table : SweepTable
        The study's results.
    dimension : {2, 3}
        The study's dimension.
    replicas : int
        Runs a point.
    overrides : sequence of str
        The study's model choices (``--set``), empty for the default.
    states : dict of str to SweepTable
        State -> the table of its runs alone (:func:`hydrojam.study.table.state_tables`).
    results : list of ClaimResult
        The claims checked on ``table``.
    run_commits : tuple of str, optional
        The commits of the code that computed the runs.

    Returns
    -------
    str
    """
    by_id = {c.claim.id: c for c in results}
    per_state = {n: {c.claim.id: c for c in check_state_claims(t, dimension)} for n, t in states.items()} \
        if len(states) > 1 else {}
    points = _distinct_points(table, dimension)
    done = sum(_finished_runs(r, replicas) for r in points.values())
    cells, seen = [], set()
    for sw in paper_sweeps(dimension):
        for r in sorted_by(rows_of(table, sw.name), sw.field):
            if r.get("key") not in seen and r.get("states"):
                seen.add(r.get("key"))
                label = sw.symbol + ("w" if sw.reading == "width" else "")
                cells.append(f"{label} {fmt_param(number(r.get(sw.field)), sw.unit)}: "
                             + str(r.get("states")).replace("; ", ", "))
    verdicts = []
    for cid in _claim_ids(dimension):
        res = by_id.get(cid)
        if res is None:
            verdicts.append("—")
            continue
        extra = [f"{n}: {per_state[n][cid].verdict}" + (f" ({_PARTIAL})" if _PARTIAL_MARK in per_state[n][cid].summary else "")
                 for n in per_state
                 if cid in per_state[n] and not str(per_state[n][cid].verdict).startswith("undetermined")]
        verdicts.append(str(res.verdict) + ("; " + ", ".join(extra) if extra else ""))
    code = ", ".join(f"`{c[:7]}`" for c in run_commits) or "—"
    choice = ", ".join(f"`{o}`" for o in overrides) or DEFAULT_CHOICE
    return (f"| {choice} | {done} of {len(points) * replicas} | {'; '.join(cells) or '—'} | "
            + " | ".join(verdicts) + f" | {code} |")


def write_sensitivity_row(page: str | os.PathLike, name: str, dimension: int, row: str) -> bool:
    """Put ``row`` (:func:`sensitivity_row`) into the section ``KIND sensitivity`` of ``page``
    (atomically), replacing the row of the same model choice and keeping the others, the default's
    first; False where the page has no such section.

    Parameters
    ----------
    page : str or os.PathLike
        A Markdown page.
    name : str
        The study's name (its kind and model choices).
    dimension : {2, 3}
        The study's dimension (the table's claims).
    row : str
        The study's row.

    Returns
    -------
    bool
        Whether the section was written.
    """
    path = Path(page)
    text = path.read_text(encoding="utf-8")
    section = _kind(name) + SENSITIVITY
    pattern = _section(section)
    found = pattern.search(text)
    if not found:
        return False
    header = _sensitivity_header(dimension)
    rows = {}  # the first cell (the model choice) -> its row
    for line in [*found.group(1).splitlines(), row]:
        if line.startswith("| ") and line != header[0]:
            rows[line.split(" | ", 1)[0]] = line
    ordered = sorted(rows, key=lambda k: (k != "| " + DEFAULT_CHOICE, k))
    body = "\n".join([_begin(section), *header, *(rows[k] for k in ordered), _end(section)])
    write_text_atomic(path, pattern.sub(lambda _: body, text))
    return True


def write_figure_section(page: str | os.PathLike, name: str, figures: Sequence[tuple[str, Path]]) -> list[Path]:
    """Show a study's figures on ``page``: where it holds the section ``NAME figures``, copy each
    figure (atomically) into ``_static/NAME/`` beside the page, remove the files there that are no
    longer the study's, and write the section: one image a figure, linked relative to the page.

    Parameters
    ----------
    page : str or os.PathLike
        A Markdown page.
    name : str
        The study's name.
    figures : sequence of (str, Path)
        Each figure's caption (the image's alternative text) and its file (a PNG the study wrote).

    Returns
    -------
    list of Path
        The copies written; empty where the page has no such section (nothing is written).
    """
    path = Path(page)
    section = name + FIGURES
    text = path.read_text(encoding="utf-8")
    pattern = _section(section)
    if not pattern.search(text):
        return []
    folder = path.parent / "_static" / name
    written, lines = [], []
    for caption, source in figures:
        target = folder / Path(source).name
        with atomic_path(target) as tmp:
            shutil.copyfile(source, tmp)
        written.append(target)
        lines += [f"![{caption}](_static/{name}/{target.name})", ""]
    for old in folder.glob("*.png"):
        if old not in written:
            old.unlink()
    body = "\n".join([_begin(section), *lines[:-1], _end(section)])
    write_text_atomic(path, pattern.sub(lambda _: body, text))
    return written
