"""The actuator design: one validated, frozen description of what to simulate (docs/actuator.md, "Design").

A :class:`Design` is read from and written to TOML. Units: length mm, stress MPa, temperature K,
chemical potential k_B T. Every invalid input raises :class:`DesignError` with one line naming
the field (dotted, e.g. ``stimulus.temperature``), the problem, the allowed range and the value
given.

Geometry (docs/decisions.md, "Geometry"): x is the bending direction (strain-limit layer on the -x side),
z the actuator axis (clamped top at z = 0, free end at z = -L), y the depth (3D only).
"""

from __future__ import annotations

import math
import os
import textwrap
import tomllib
import typing
from pathlib import Path
from typing import Literal

import tomli_w
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from hydrojam._io import read_toml, write_text_atomic
from hydrojam._validation import explain_error, field_range, field_unit, non_finite_message, submodel
from hydrojam.materials.energies import WATER_RANGE_K, HydrogelParams, NeoHookean, Yeoh
from hydrojam.materials.kinetics import DEFAULT_DIFFUSIVITY

_REL_TOL = 1e-9  # relative slack of the fit checks: a derived cavity fits exactly
_YEOH_I1_RANGE = 30.0  # Yeoh stiffness must stay positive for 0 <= I1bar - 3 <= this (uniaxial stretch ~5.6)

__all__ = [
    "DEFAULT_MESH_SIZE_MM",
    "MAX_CAVITY_MM",
    "MAX_CHAMBERS_2D",
    "ROUND_AXIS_CHAMBERS",
    "ChamberSpec",
    "MAX_ELEMENTS",
    "MAX_WALL_MM",
    "Design",
    "DesignError",
    "ElastomerSpec",
    "GelSpec",
    "MAX_JITTER",
    "MAX_REPLICAS",
    "MeshSpec",
    "ReplicaSpec",
    "StimulusSpec",
    "apply_overrides",
    "default_design",
    "design_from_dict",
    "design_to_toml",
    "load_design",
    "with_replicas",
    "write_design",
]


class DesignError(ValueError):
    """Invalid design: one line naming the field (dotted, e.g. 'stimulus.temperature') and its allowed range."""


def _g(x: float) -> str:
    return f"{x:g}"


_CONFIG = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class ElastomerSpec(BaseModel):
    """An elastomer (membrane or strain-limit layer): compressible neo-Hookean or Yeoh (docs/model.md).

    Default: Ecoflex 00-30, G = 0.023 MPa, Poisson's ratio 0.45. Checks: C20, C30 only with
    ``model = "yeoh"``; a Yeoh fit must keep dW/dI1bar = C10 + 2 C20 x + 3 C30 x^2 > 0 for
    0 <= x = I1bar - 3 <= 30 (uniaxial stretch up to about 5.6), i.e. a positive shear stiffness
    over the strains the elastomer can reach.
    """

    model_config = _CONFIG

    model: Literal["neo-hookean", "yeoh"] = Field("neo-hookean", description="constitutive model")
    shear_modulus: float = Field(
        0.023, gt=0, le=1e4, description="initial shear modulus G (neo-Hookean G; Yeoh 2 C10) [MPa]"
    )
    c20: float = Field(0.0, description="Yeoh coefficient C20, only with model = 'yeoh' [MPa]")
    c30: float = Field(0.0, description="Yeoh coefficient C30, only with model = 'yeoh' [MPa]")
    poisson_ratio: float = Field(
        0.45, ge=0, lt=0.5, description="small-strain Poisson's ratio nu; bulk modulus derived [-]"
    )

    @model_validator(mode="after")
    def _check(self) -> ElastomerSpec:
        if self.model == "neo-hookean":
            for name in ("c20", "c30"):
                value = getattr(self, name)
                if value != 0.0:
                    raise ValueError(
                        f"{name}: only for model = 'yeoh'; must be 0 with model 'neo-hookean' (got {_g(value)})"
                    )
            return self
        c10, c20, c30 = 0.5 * self.shear_modulus, self.c20, self.c30
        xs = [0.0, _YEOH_I1_RANGE]
        if c30 > 0.0:
            xs.append(min(max(-c20 / (3.0 * c30), 0.0), _YEOH_I1_RANGE))
        x = min(xs, key=lambda x: c10 + 2.0 * c20 * x + 3.0 * c30 * x * x)
        if c10 + 2.0 * c20 * x + 3.0 * c30 * x * x <= 0.0:
            name = "c30" if c30 < 0.0 else "c20"
            raise ValueError(
                f"{name}: the Yeoh shear stiffness C10 + 2 C20 x + 3 C30 x^2 (C10 = shear_modulus/2) "
                f"is <= 0 at x = I1bar - 3 = {x:.3g}; it must stay > 0 for 0 <= x <= {_g(_YEOH_I1_RANGE)} "
                f"(got C10 = {_g(c10)}, C20 = {_g(c20)}, C30 = {_g(c30)} MPa)"
            )
        return self

    def material(self) -> NeoHookean | Yeoh:
        """The energy density: NeoHookean(G, nu) or Yeoh(C10 = G/2, C20, C30, nu)."""
        if self.model == "yeoh":
            return Yeoh(c10=0.5 * self.shear_modulus, c20=self.c20, c30=self.c30, poisson_ratio=self.poisson_ratio)
        return NeoHookean(shear_modulus=self.shear_modulus, poisson_ratio=self.poisson_ratio)


#: most points a schedule may have (a schedule is a few steps, ramps or cycles, not a data log)
MAX_SCHEDULE_POINTS = 1000
#: largest schedule time [s] (about 30 years: anything longer is a unit mistake)
MAX_SCHEDULE_TIME_S = 1e9
#: largest collective diffusion coefficient [mm^2/s]: 1e-8 m^2/s, four times the self-diffusion
#: coefficient of water at 25 C (2.3e-9 m^2/s); a gel's collective D is 1e-11 to 1e-9 m^2/s
MAX_DIFFUSIVITY = 1e-2


class GelSpec(HydrogelParams):
    """The hydrogel: the PNIPAM constants of :class:`HydrogelParams` and the collective diffusion
    coefficient of its swelling kinetics (used by a time-resolved stimulus only)."""

    diffusivity: float = Field(
        DEFAULT_DIFFUSIVITY, gt=0, le=MAX_DIFFUSIVITY,
        description="collective diffusion coefficient D of the gel's swelling kinetics, used with "
        "stimulus.schedule only (docs/kinetics.md) [mm^2/s]",
    )

    def params(self) -> HydrogelParams:
        """The gel constants alone (without the diffusivity)."""
        return HydrogelParams(**self.model_dump(exclude={"diffusivity"}))


class StimulusSpec(BaseModel):
    """Target stimulus (mu [k_B T], T [K]) and the path from the as-prepared (mu0, T0) to it
    (docs/actuator.md, "Stimulus path").

    With a ``schedule`` ([[t_s, T_K], ...]: times strictly increasing from 0, temperatures in
    liquid water's range, 2 to 1000 points, linear in between; a step is a short ramp) the run
    is time-resolved (docs/actuator.md, "Actuation in time"): the particles meet the solvent at
    ``mu`` at t = 0 and the temperature follows the schedule; ``temperature`` is then ignored
    (the resolved design writes the schedule's last temperature there) and ``path`` must be
    "swelling".
    """

    model_config = _CONFIG

    temperature: float = Field(275.0, ge=WATER_RANGE_K[0], le=WATER_RANGE_K[1], description="target temperature T [K]")
    mu: float = Field(0.0, le=0.0, description="target solvent chemical potential mu; 0 = pure water [kT]")
    path: Literal["swelling", "linear"] = Field(
        "swelling",
        description="load path from (mu0, T0) to the target: 'linear' in the load parameter s, or "
        "'swelling' (s spaced evenly in the free-swelling log-volume)",
    )
    schedule: tuple[tuple[float, float], ...] | None = Field(
        None,
        description="time-resolved temperature: [[t_s, T_K], ...], times strictly increasing from 0, "
        f"T in [{WATER_RANGE_K[0]}, {WATER_RANGE_K[1]}] K, 2 to {MAX_SCHEDULE_POINTS} points, linear in between; "
        "replaces temperature [s, K]",
    )

    @model_validator(mode="before")
    @classmethod
    def _schedule_shape(cls, data):
        if not isinstance(data, dict) or data.get("schedule") is None:
            return data
        raw = data["schedule"]
        form = "expected a list of [time_s, temperature_K] points, e.g. [[0, 300], [60, 275], [7200, 275]]"
        if not isinstance(raw, (list, tuple)):
            raise ValueError(f"schedule: {form} (got {raw!r:.60})")
        points = []
        for k, p in enumerate(raw):
            if not (isinstance(p, (list, tuple)) and len(p) == 2
                    and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in p)):
                raise ValueError(f"schedule: point {k}: {form} (got {p!r:.60})")
            points.append(tuple(p))
        return {**data, "schedule": tuple(points)}

    @model_validator(mode="after")
    def _check_schedule(self) -> StimulusSpec:
        pts = self.schedule
        if pts is None:
            return self
        lo, hi = WATER_RANGE_K
        if not 2 <= len(pts) <= MAX_SCHEDULE_POINTS:
            raise ValueError(f"schedule: needs 2 to {MAX_SCHEDULE_POINTS} [time_s, temperature_K] points (got {len(pts)})")
        if pts[0][0] != 0.0:
            raise ValueError(f"schedule: the first time must be 0 s (the particles meet the solvent at t = 0; got {_g(pts[0][0])} s)")
        for k, ((t0, _), (t1, _)) in enumerate(zip(pts[:-1], pts[1:])):
            if not t1 > t0:
                raise ValueError(f"schedule: times must increase strictly; point {k + 1} has t = {_g(t1)} s "
                                 f"after t = {_g(t0)} s")
        if pts[-1][0] > MAX_SCHEDULE_TIME_S:
            raise ValueError(f"schedule: times must be <= {_g(MAX_SCHEDULE_TIME_S)} s (got {_g(pts[-1][0])} s)")
        for k, (_, T) in enumerate(pts):
            if not lo <= T <= hi:
                raise ValueError(f"schedule: point {k}: temperature must be in liquid water's range "
                                 f"[{lo}, {hi}] K (got {_g(T)} K)")
        if self.path != "swelling":
            raise ValueError(f"path: only 'swelling' with a schedule (the load parameter follows the "
                             f"swelling in time; got {self.path!r})")
        return self


class MeshSpec(BaseModel):
    """Finite-element mesh controls: quadratic triangles (2D) / tetrahedra (3D)."""

    model_config = _CONFIG

    size: float | None = Field(
        None, gt=0,
        description="target element edge length, quadratic elements [mm]; omitted: the dimension's default "
        "(DEFAULT_MESH_SIZE_MM: 2.0 in 2D, 2.0 in 3D; docs/actuator.md, \"Mesh convergence\")",
    )
    symmetry: bool = Field(
        True,
        description="3D only: model the half y >= 0 (y = 0 is a symmetry plane: u_y = 0 there, results "
        "mirrored); false: the whole actuator. Must stay true in 2D",
    )


#: mesh.size left out [mm], by dimension: the coarsest size whose angle, tip and curling index lie within
#: the spread of the finest size run (benchmarks/mesh.py; docs/actuator.md, "Mesh convergence")
DEFAULT_MESH_SIZE_MM = {2: 2.0, 3: 2.0}

#: thickest wall or strain-limit layer [mm]: 1 m, the particle diameter's own bound; a
#: hand-made chamber's walls are millimetres, anything near this is a unit mistake
MAX_WALL_MM = 1000.0
#: thinnest wall (t0, t1, and each half h/2 of the strain-limit layer, which is meshed in two
#: halves) as a share of mesh.size: thinner, one quadratic element spans it with an aspect ratio
#: above 4, a row of slivers
MIN_WALL_PER_MESH = 0.25
#: most elements a design's mesh may have, estimated from its size (:meth:`Design.estimated_elements`):
#: ten times the paper's largest (the 3D study at mesh.size 2 mm, about 1e5); beyond it gmsh runs
#: for hours and the solver needs more memory than a workstation holds
MAX_ELEMENTS = 1_000_000
#: smallest clearance as a share of the actuator's larger outer size (length or width): below
#: it the gaps drawn in the geometry approach the round-off of the coordinates
MIN_CLEARANCE_PER_SIZE = 1e-6
#: largest cavity size [mm]: 200 m, above the largest cavity derived from the particles
#: (100 layers of 1 m particles with 0.25 m clearances, 125 m)
MAX_CAVITY_MM = 2e5

#: most replicas of one design (each is a full simulation)
MAX_REPLICAS = 1000
#: largest jitter of a particle centre, as a share of the clearance c: two neighbours moving
#: toward each other by 0.1 c each keep a gap of 0.8 c, the contact barrier's activation distance
#: (hydrojam.actuator.model.DHAT_PER_CLEARANCE), so every replica starts stress-free
MAX_JITTER = 0.1
#: largest seed (TOML integers are signed 64-bit)
MAX_SEED = 2**63 - 1


class ReplicaSpec(BaseModel):
    """Replicas: the same design run ``count`` times, each with its own seeded perturbation of
    the as-prepared state (docs/replicas.md).

    Replica k (0-based) moves every particle's centre rigidly by an offset drawn uniformly from
    a disk of radius ``jitter`` x clearance, from the random stream of (``seed``, k); replica 0
    is the design as drawn (no offset), so one replica is the plain run. A single run is the
    replica ``index`` (0 unless the file is one replica of a set, as the replica's folder holds
    it); ``index`` > 0 only with ``count`` = 1.
    """

    model_config = _CONFIG

    count: int = Field(1, ge=1, le=MAX_REPLICAS, description="replicas to run; 1: the design alone [-]")
    seed: int = Field(0, ge=0, le=MAX_SEED, description="seed of the replicas' perturbations [-]")
    jitter: float = Field(
        MAX_JITTER, gt=0, le=MAX_JITTER,
        description="largest particle-centre offset as a share of the clearance (<= 0.1: every gap stays >= "
        "the barrier's activation distance 0.8 c) [-]",
    )
    index: int = Field(
        0, ge=0, le=MAX_REPLICAS - 1,
        description="which replica a single run is: 0 the design as drawn, k > 0 perturbed from (seed, k); "
        "> 0 only with count = 1 [-]",
    )

    @model_validator(mode="after")
    def _check(self) -> ReplicaSpec:
        if self.index > 0 and self.count != 1:
            raise ValueError(f"index: > 0 only with count = 1 (a set of {self.count} replicas runs indices "
                             f"0 to {self.count - 1}; got index {self.index})")
        return self


#: most chambers of a design: two side by side along x in 2D
MAX_CHAMBERS_2D = 2
#: the number of chambers that are laid round the actuator's axis, 120 deg apart (3D, the whole
#: actuator): the count of [[chambers]] tables picks the layout (two: side by side along x)
ROUND_AXIS_CHAMBERS = 3
#: where a multi-chamber design's strain-limit layer goes ("core": three chambers round the axis only)
STRAIN_LIMIT_POSITIONS = ("-x", "+x", "middle", "none", "core")


class ChamberSpec(BaseModel):
    """One chamber of a multi-chamber design (``Design.chambers``): its particles, gel and,
    optionally, its own temperature. A key left out takes the design's own (its particle_layers,
    particles_per_layer, particle_diameter, hydrogel; the stimulus' temperature); ``cavity_width``
    left out is derived from the particles, m d + (m + 1) c."""

    model_config = _CONFIG

    particle_layers: int | None = Field(None, ge=1, le=100, description="particle layers along the axis PL; "
                                        "omitted: the design's [-]")
    particles_per_layer: int | None = Field(None, ge=1, le=20, description="particles side by side in a layer; "
                                            "omitted: the design's [-]")
    particle_diameter: float | None = Field(None, gt=0, le=1000, description="as-prepared particle diameter d; "
                                            "omitted: the design's [mm]")
    cavity_width: float | None = Field(None, gt=0, le=MAX_CAVITY_MM, description="this chamber's cavity width "
                                       "along x; omitted: m d + (m + 1) c [mm]")
    temperature: float | None = Field(None, ge=WATER_RANGE_K[0], le=WATER_RANGE_K[1],
                                      description="target temperature of the water this chamber is perfused "
                                      "with; omitted: stimulus.temperature [K]")
    hydrogel: GelSpec | None = Field(None, description="this chamber's gel; omitted: the design's hydrogel")


class Design(BaseModel):
    """A particle-jamming bending actuator: geometry, materials, stimulus and mesh (docs/actuator.md).

    Cavity sizes left out (None) are derived from the particles: width ``m d + (m + 1) c``, length
    ``PL d + (PL + 1) c``, depth (3D) ``d + 2 c`` (m particles per layer, PL layers, d diameter,
    c clearance). Checks, each naming the field and the bound it must meet:

    - numbers are finite (no inf/nan, including the hydrogel constants);
    - ``clearance < particle_diameter / 4`` (a clearance is a gap, not a loose fit);
    - the particles fit: across ``m d + (m + 1) c <= cavity_width``, along
      ``PL d + (PL + 1) c <= cavity_length``, and in 3D ``d + 2 c <= cavity_depth``
      (relative tolerance 1e-9): the initial mesh must be intersection-free;
    - ``cavity_depth`` and ``mesh.symmetry = false`` only with ``dimension = 3`` (2D is plane
      strain: no depth to set or cut);
    - ``mesh.size <= particle_diameter / 4`` (about 12 or more quadratic edges round a particle)
      and ``mesh.size <= cavity_length``;
    - the geometry can be built: every wall (t0, t1 and each half h/2 of the strain-limit layer)
      at least ``mesh.size / 4`` thick (:data:`MIN_WALL_PER_MESH`), the clearance at least 1e-6 of
      the actuator's length or width (:data:`MIN_CLEARANCE_PER_SIZE`), and the mesh at most
      :data:`MAX_ELEMENTS` elements (:meth:`estimated_elements`);
    - the elastomers' own checks (:class:`ElastomerSpec`).
    """

    model_config = _CONFIG

    dimension: Literal[2, 3] = Field(
        2, description="2: plane strain in x-z (cylindrical particles); 3: spheres (tetrahedra; half model by default, see mesh.symmetry)"
    )
    particle_diameter: float = Field(16.0, gt=0, le=1000, description="as-prepared particle diameter d [mm]")
    particle_layers: int = Field(5, ge=1, le=100, description="number of particle layers along the axis PL [-]")
    particles_per_layer: int = Field(1, ge=1, le=20, description="particles side by side in each layer (along x) [-]")
    clearance: float = Field(
        0.1, gt=0, description="initial gap between particles, and between particles and walls c [mm]"
    )
    side_wall_thickness: float = Field(2.0, gt=0, le=MAX_WALL_MM, description="membrane side-wall thickness t0 [mm]")
    end_wall_thickness: float = Field(4.0, gt=0, le=MAX_WALL_MM, description="membrane top and bottom wall thickness t1 [mm]")
    strain_limit_thickness: float = Field(
        8.0, gt=0, le=MAX_WALL_MM, description="strain-limit layer thickness h, bonded on the -x face over the full length [mm]"
    )
    strain_limit_width: float | None = Field(
        None,
        gt=0,
        le=MAX_WALL_MM,
        description="3D only: the strain-limit layer's width along y, a strip centred on the -x face (the paper's "
        "other reading of h); omitted: the face's full width cavity_depth + 2 side_wall_thickness [mm]",
    )
    strain_limit_helix_deg: float | None = Field(
        None,
        gt=-90,
        lt=90,
        description="3D full model only: the strip wound round the chamber at this angle to the axis, a helix "
        "(positive: from the clamp toward the free end it runs toward +y on the -x face; docs/chambers.md, "
        "\"A helical strip\"); omitted or 0: the straight strip [deg]",
    )
    chamber_wall_thickness: float | None = Field(
        None, gt=0, le=MAX_WALL_MM,
        description="with chambers: the shared wall between neighbouring chambers; omitted: side_wall_thickness [mm]",
    )
    strain_limit_position: Literal["-x", "+x", "middle", "none", "core"] | None = Field(
        None,
        description="with chambers: two side by side: the strain-limit layer on the -x or +x outer face, as the "
        "middle wall (of thickness chamber_wall_thickness), or none; omitted: -x. Three round the axis: none, "
        "or core (a rod of diameter strain_limit_thickness on the axis); omitted: none",
    )
    cavity_width: float | None = Field(
        None,
        gt=0, le=MAX_CAVITY_MM,
        description="cavity width along x; omitted: particles_per_layer d + (particles_per_layer + 1) c [mm]",
    )
    cavity_length: float | None = Field(
        None, gt=0, le=MAX_CAVITY_MM, description="cavity length along the axis z; omitted: PL d + (PL + 1) c [mm]"
    )
    cavity_depth: float | None = Field(
        None, gt=0, le=MAX_CAVITY_MM, description="cavity depth along y, 3D only (three chambers round the axis: each "
        "cylindrical cavity's diameter); omitted: d + 2 c [mm]"
    )
    friction: float = Field(
        0.01,
        ge=0,
        le=2,
        description="Coulomb friction coefficient, particle-particle and particle-membrane; default 0.01: "
        "swollen hydrogel in water (docs/contact.md, \"Friction\") [-]",
    )
    friction_slip: float | None = Field(
        None,
        gt=0,
        le=1,
        description="tangential slip below which friction is static (IPC's eps_v times the step); "
        "omitted: 1% of the contact activation distance (docs/contact.md, \"The static slip\") [mm]",
    )
    membrane: ElastomerSpec = Field(ElastomerSpec(), description="membrane elastomer (default Ecoflex 00-30)")
    strain_limit_layer: ElastomerSpec = Field(
        ElastomerSpec(), description="strain-limit layer elastomer (default Ecoflex 00-30)"
    )
    hydrogel: GelSpec = Field(
        GelSpec(),
        description="PNIPAM gel constants and diffusivity; mu0 is derived from the stress-free as-prepared "
        "state (lambda0, T0)",
    )
    stimulus: StimulusSpec = Field(StimulusSpec(), description="target stimulus and load path")
    mesh: MeshSpec = Field(MeshSpec(), description="finite-element mesh")
    replicas: ReplicaSpec = Field(
        ReplicaSpec(), description="replicas: the design run several times from seeded perturbations of "
        "its as-prepared particle positions (docs/replicas.md)"
    )
    chambers: tuple[ChamberSpec, ...] | None = Field(
        None,
        description="two chambers side by side along x ([[chambers]] tables, the first on the -x side), or three "
        "round the axis z, 120 deg apart (3D, mesh.symmetry = false; the first on +x, then toward +y), each "
        "with its particles, gel and temperature; omitted: one chamber (docs/chambers.md)",
    )

    @model_validator(mode="before")
    @classmethod
    def _chambers_tuple(cls, data):
        if isinstance(data, dict) and isinstance(data.get("chambers"), list):  # TOML's array of tables
            return {**data, "chambers": tuple(data["chambers"])}
        return data

    # ---------------------------------------------------------------- derived geometry

    @property
    def resolved_cavity_width(self) -> float:
        """Cavity width along x [mm], given or derived."""
        if self.cavity_width is not None:
            return self.cavity_width
        m = self.particles_per_layer
        return m * self.particle_diameter + (m + 1) * self.clearance

    @property
    def resolved_cavity_length(self) -> float:
        """Cavity length along the axis z [mm], given or derived (with chambers: the longest
        chamber's column)."""
        if self.cavity_length is not None:
            return self.cavity_length
        if self.chambers is not None:
            c = self.clearance
            return max(ch.particle_layers * ch.particle_diameter + (ch.particle_layers + 1) * c
                       for ch in self.resolved_chambers)
        pl = self.particle_layers
        return pl * self.particle_diameter + (pl + 1) * self.clearance

    @property
    def resolved_chambers(self) -> tuple[ChamberSpec, ...] | None:
        """The chambers with every key written out (the design's own where a chamber leaves one
        out, cavity widths derived from the particles); None for a single-chamber design."""
        if self.chambers is None:
            return None
        out = []
        for ch in self.chambers:
            pl = self.particle_layers if ch.particle_layers is None else ch.particle_layers
            m = self.particles_per_layer if ch.particles_per_layer is None else ch.particles_per_layer
            d = self.particle_diameter if ch.particle_diameter is None else ch.particle_diameter
            w = m * d + (m + 1) * self.clearance if ch.cavity_width is None else ch.cavity_width
            if self.round_axis:  # a cylindrical cavity of diameter cavity_depth: no width along x
                w = ch.cavity_width
            out.append(ChamberSpec(
                particle_layers=pl, particles_per_layer=m, particle_diameter=d, cavity_width=w,
                temperature=self.stimulus.temperature if ch.temperature is None else ch.temperature,
                hydrogel=self.hydrogel if ch.hydrogel is None else ch.hydrogel))
        return tuple(out)

    @property
    def round_axis(self) -> bool:
        """Three chambers round the axis (:data:`ROUND_AXIS_CHAMBERS` [[chambers]] tables), 120 deg apart."""
        return self.chambers is not None and len(self.chambers) == ROUND_AXIS_CHAMBERS

    @property
    def round_cavity_diameter(self) -> float:
        """Three chambers round the axis: the diameter [mm] each cylindrical cavity is drawn with,
        cavity_depth D widened by twice the sagitta of a chord mesh.size/2 long on its radius,
        D + 2 (h/2)^2 / (4 D) (h = mesh.size). The contact sees the quadratic faces as their
        straight pieces, about h/2 across, which lie that far inside the cylinder: drawn at D, they
        would eat into the clearance (at h = 4 mm, D = 16.2 mm, the gap to the sphere measured
        0.069 mm for a clearance of 0.1 mm, under the barrier's reach of 0.08 mm, so that the
        as-prepared state was not stress-free)."""
        D, h = self.resolved_cavity_depth, self.mesh_size
        return D + 2.0 * (h / 2.0) ** 2 / (4.0 * D)

    @property
    def chamber_radius(self) -> float:
        """Three chambers round the axis: the distance r_c of each cylindrical cavity's axis from the
        actuator's [mm]. The wall between neighbouring cavities (drawn diameter D,
        :attr:`round_cavity_diameter`) is chamber_wall_thickness t_w thick at its thinnest,
        r_c = (D + t_w) / sqrt(3); with a core of diameter h, each cavity also keeps t_w from the
        core, r_c >= D/2 + t_w + h/2."""
        D, t_w = self.round_cavity_diameter, self.resolved_chamber_wall
        r_c = (D + t_w) / math.sqrt(3.0)
        if self.resolved_strain_limit_position == "core":
            r_c = max(r_c, D / 2 + t_w + self.strain_limit_thickness / 2)
        return r_c

    @property
    def outer_radius(self) -> float:
        """Three chambers round the axis: the body's radius R = r_c + D/2 + side_wall_thickness [mm]
        (D the drawn diameter, :attr:`round_cavity_diameter`)."""
        return self.chamber_radius + self.round_cavity_diameter / 2 + self.side_wall_thickness

    @property
    def resolved_chamber_wall(self) -> float:
        """The shared wall between chambers [mm]: chamber_wall_thickness, else side_wall_thickness."""
        return self.side_wall_thickness if self.chamber_wall_thickness is None else self.chamber_wall_thickness

    @property
    def resolved_strain_limit_position(self) -> str:
        """Where the strain-limit layer lies: "-x" (the single chamber's), "+x", "middle" or "none";
        three chambers round the axis: "none" (their default) or "core"."""
        if self.strain_limit_position is None:
            return "none" if self.round_axis else "-x"
        return self.strain_limit_position

    @property
    def resolved_cavity_depth(self) -> float:
        """Cavity depth along y [mm], given or derived (used in 3D only; with chambers: the largest
        chamber's particle diameter + 2 c)."""
        if self.cavity_depth is not None:
            return self.cavity_depth
        if self.chambers is not None:
            return max(ch.particle_diameter for ch in self.resolved_chambers) + 2.0 * self.clearance
        return self.particle_diameter + 2.0 * self.clearance

    @property
    def length(self) -> float:
        """Actuator length L = cavity_length + 2 t1 [mm]."""
        return self.resolved_cavity_length + 2.0 * self.end_wall_thickness

    @property
    def width(self) -> float:
        """Actuator width along x, h + 2 t0 + cavity_width [mm]; with chambers the cavities' widths,
        the shared wall, 2 t0 and h where the strain-limit layer lies on an outer face; three chambers
        round the axis: the body's diameter 2 R (:attr:`outer_radius`)."""
        if self.round_axis:
            return 2.0 * self.outer_radius
        if self.chambers is not None:
            outer = self.strain_limit_thickness if self.resolved_strain_limit_position in ("-x", "+x") else 0.0
            return (sum(ch.cavity_width for ch in self.resolved_chambers) + self.resolved_chamber_wall
                    + 2.0 * self.side_wall_thickness + outer)
        return self.strain_limit_thickness + 2.0 * self.side_wall_thickness + self.resolved_cavity_width

    @property
    def mesh_size(self) -> float:
        """Target element edge length [mm]: mesh.size, else the dimension's default
        (:data:`DEFAULT_MESH_SIZE_MM`)."""
        return DEFAULT_MESH_SIZE_MM[self.dimension] if self.mesh.size is None else self.mesh.size

    def estimated_elements(self) -> float:
        """About how many elements the mesh has [-]: the actuator's outer area (2D) or volume (3D;
        half of it for the half model) over that of an equilateral triangle or regular tetrahedron
        of edge ``mesh.size``. gmsh refines near the particles and thin walls: the real count is up
        to about twice this (1492 against 1443 for the default design). inf where the sizes overflow."""
        h = self.mesh_size
        area = self.width * self.length
        if self.dimension == 2:
            return area / (math.sqrt(3.0) / 4.0 * h * h)
        depth = self.resolved_cavity_depth + 2.0 * self.side_wall_thickness
        volume = area * depth * (0.5 if self.mesh.symmetry else 1.0)
        if self.round_axis:  # a cylinder, the whole actuator
            volume = math.pi * self.outer_radius**2 * self.length
        return volume / (h**3 / (6.0 * math.sqrt(2.0)))

    def resolved(self) -> Design:
        """A copy with cavity_width, cavity_length (and cavity_depth in 3D) and mesh.size written out
        explicitly, and with a schedule, stimulus.temperature set to the schedule's last temperature."""
        update = {"cavity_width": self.resolved_cavity_width, "cavity_length": self.resolved_cavity_length}
        if self.chambers is not None:  # each chamber has its own width; the shared keys written out
            update = {"cavity_length": self.resolved_cavity_length, "chambers": self.resolved_chambers,
                      "chamber_wall_thickness": self.resolved_chamber_wall,
                      "strain_limit_position": self.resolved_strain_limit_position}
            if self.dimension == 3:
                update["cavity_depth"] = self.resolved_cavity_depth
        if self.dimension == 3:
            update["cavity_depth"] = self.resolved_cavity_depth
        if self.stimulus.schedule is not None:
            update["stimulus"] = self.stimulus.model_copy(update={"temperature": self.stimulus.schedule[-1][1]})
        update["mesh"] = self.mesh.model_copy(update={"size": self.mesh_size})
        return self.model_copy(update=update)

    def replica(self, k: int) -> Design:
        """Replica ``k`` of this design (0 <= k < replicas.count) as a single run: the same design
        with ``replicas`` count 1 and index k (seed and jitter kept); a single run (count 1) is its
        own replica 0. ValueError outside the range."""
        n = self.replicas.count
        if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < n:
            raise ValueError(f"replica: must be an integer in [0, {n - 1}] (got {k!r})")
        if n == 1:
            return self
        return self.model_copy(update={"replicas": self.replicas.model_copy(update={"count": 1, "index": k})})

    # ---------------------------------------------------------------- consistency

    def _check_chambers(self) -> None:
        """The checks of a multi-chamber design (its fields' own ranges aside)."""
        n = len(self.chambers)
        if self.dimension == 2 and not n == MAX_CHAMBERS_2D:
            raise ValueError(f"chambers: 2D takes {MAX_CHAMBERS_2D} chambers side by side along x (three round the "
                             f"axis would need dimension = 3; got {n})")
        if self.dimension == 3 and n not in (MAX_CHAMBERS_2D, ROUND_AXIS_CHAMBERS):
            raise ValueError(f"chambers: 3D takes {MAX_CHAMBERS_2D} chambers side by side along x or "
                             f"{ROUND_AXIS_CHAMBERS} round the axis (got {n})")
        if self.round_axis:
            self._check_round_axis()
        elif self.strain_limit_position == "core":
            raise ValueError("strain_limit_position: 'core' only with three chambers round the axis (two side by "
                             "side take '-x', '+x', 'middle' or 'none'; got 'core')")
        if self.strain_limit_width is not None:
            raise ValueError(f"strain_limit_width: not with chambers (the strain-limit layer spans its face; got "
                             f"strain_limit_width {_g(self.strain_limit_width)} mm)")
        if self.cavity_width is not None:
            raise ValueError(f"cavity_width: not with chambers: each chamber sets its own cavity_width (got "
                             f"cavity_width {_g(self.cavity_width)} mm)")
        if self.stimulus.schedule is not None:
            raise ValueError("stimulus.schedule: not with chambers: a time-resolved run has one temperature "
                             "(give each chamber its target temperature instead)")
        c, h = self.clearance, self.mesh_size
        length = self.resolved_cavity_length
        depth = self.resolved_cavity_depth
        for k, ch in enumerate(self.resolved_chambers):
            d, m, pl = ch.particle_diameter, ch.particles_per_layer, ch.particle_layers
            where = f"chambers.{k}"
            if not c < d / 4.0:
                raise ValueError(f"{where}.particle_diameter: must be > 4 clearance = {_g(4 * c)} mm (a clearance "
                                 f"is a gap, not a loose fit; got {_g(d)} mm)")
            if h > d / 4.0:
                raise ValueError(f"mesh.size: must be <= {where}.particle_diameter/4 = {_g(d / 4.0)} mm so that "
                                 f"about 12 quadratic edges or more go round a particle (got {_g(h)} mm)")
            fits = [("cavity_length", pl, length)]
            if not self.round_axis:  # round the axis, the cylinder's diameter is cavity_depth
                fits.insert(0, ("cavity_width", m, ch.cavity_width))
            if self.dimension == 3:
                fits.append(("cavity_depth", 1, depth))
            for name, count, size in fits:
                need = count * d + (count + 1) * c
                if need > size * (1.0 + _REL_TOL):
                    field = f"{where}.{name}" if name == "cavity_width" else name
                    raise ValueError(
                        f"{field}: chamber {k}'s particles do not fit: {count} x {_g(d)} mm + {count + 1} x "
                        f"{_g(c)} mm clearance = {_g(need)} mm > {_g(size)} mm; need {field} >= {_g(need)} mm")
            for name, value in (ch.hydrogel.model_dump().items() if ch.hydrogel is not None else ()):
                if not math.isfinite(value):
                    raise ValueError(non_finite_message(f"{where}.hydrogel.{name}", value,
                                                        field_range(GelSpec, name), field_unit(GelSpec, name)))
        wall = self.resolved_chamber_wall
        if wall / 2.0 < MIN_WALL_PER_MESH * h:
            raise ValueError(
                f"chamber_wall_thickness: too thin for mesh.size {_g(h)} mm: must be >= {_g(2 * MIN_WALL_PER_MESH * h)} "
                f"mm (it is meshed in two halves, each >= mesh.size/4), else its elements are slivers (got {_g(wall)} mm)")

    def _check_round_axis(self) -> None:
        """The checks of three chambers round the axis (before their particles' fit)."""
        if self.mesh.symmetry:
            raise ValueError("mesh.symmetry: must be false with three chambers round the axis (each chamber is "
                             "activated on its own, so no plane y = 0 halves the actuator: the whole actuator is "
                             "meshed; got true)")
        if self.strain_limit_position not in (None, "none", "core"):
            raise ValueError(f"strain_limit_position: with three chambers round the axis allowed: 'none', 'core' "
                             f"(a rod on the axis; got {self.strain_limit_position!r})")
        for k, ch in enumerate(self.chambers):
            if ch.cavity_width is not None:
                raise ValueError(f"chambers.{k}.cavity_width: not with three chambers round the axis: each cavity is "
                                 f"a cylinder of diameter cavity_depth (got {_g(ch.cavity_width)} mm)")
        chambers = self.resolved_chambers
        for k, ch in enumerate(chambers):
            if ch.particles_per_layer != 1:
                field = f"chambers.{k}.particles_per_layer" if self.chambers[k].particles_per_layer is not None \
                    else "particles_per_layer"
                raise ValueError(f"{field}: must be 1 with three chambers round the axis (each cylindrical cavity "
                                 f"holds one column of spheres; got {ch.particles_per_layer})")
            for name, unit in (("particle_layers", ""), ("particle_diameter", " mm")):
                mine, first = getattr(ch, name), getattr(chambers[0], name)
                if mine != first:
                    raise ValueError(f"chambers.{k}.{name}: three chambers round the axis hold the same particles "
                                     f"(one sector of the mesh is turned round the axis): must equal chamber 0's "
                                     f"{_g(first)}{unit} (got {_g(mine)}{unit})")

    @property
    def helix_angle_deg(self) -> float:
        """The strain-limit strip's angle to the axis [deg]: ``strain_limit_helix_deg``, 0 when omitted."""
        return 0.0 if self.strain_limit_helix_deg is None else float(self.strain_limit_helix_deg)

    def max_helix_angle_deg(self) -> float:
        """The largest |strain_limit_helix_deg| [deg] at which the strip still fits across the -x face:
        a strip of width w at angle a spans w / cos(a) across the axis, at most the face's width
        cavity_depth + 2 side_wall_thickness (0 for a strip as wide as the face)."""
        face = self.resolved_cavity_depth + 2.0 * self.side_wall_thickness
        w = face if self.strain_limit_width is None else self.strain_limit_width
        return math.degrees(math.acos(min(w / face, 1.0)))

    def _check_helix(self) -> None:
        """The checks of a helical strip (a nonzero ``strain_limit_helix_deg``)."""
        a = self.helix_angle_deg
        if a == 0.0:
            return
        got = f"got strain_limit_helix_deg {_g(a)}"
        if self.dimension != 3:
            raise ValueError(f"strain_limit_helix_deg: nonzero only with dimension = 3 (2D is plane strain: a strip "
                             f"along the depth cannot wind round the chamber; {got} with dimension {self.dimension})")
        if self.chambers is not None:
            raise ValueError(f"strain_limit_helix_deg: nonzero not with chambers (their strain-limit layer spans its "
                             f"face; {got})")
        if self.mesh.symmetry:
            raise ValueError(f"strain_limit_helix_deg: nonzero only with mesh.symmetry = false (a helical strip has "
                             f"no symmetry plane y = 0: the whole actuator is meshed; {got})")
        face = self.resolved_cavity_depth + 2.0 * self.side_wall_thickness
        w = face if self.strain_limit_width is None else self.strain_limit_width
        span = w / math.cos(math.radians(a))
        if self.strain_limit_width is None:
            raise ValueError(f"strain_limit_helix_deg: nonzero needs a strain_limit_width narrower than the -x face's "
                             f"{_g(face)} mm (a strip as wide as the face cannot be wound round it; {got})")
        if span > face * (1.0 + _REL_TOL):
            raise ValueError(
                f"strain_limit_helix_deg: must be in [-{_g(self.max_helix_angle_deg())}, "
                f"{_g(self.max_helix_angle_deg())}] deg for a strip {_g(w)} mm wide: at {_g(a)} deg it spans "
                f"{_g(span)} mm across the axis, more than the -x face's {_g(face)} mm, and would wrap over the "
                f"face's edges onto itself (set a narrower strain_limit_width)")

    @model_validator(mode="after")
    def _check_consistency(self) -> Design:
        for name, value in self.hydrogel.model_dump().items():
            if not math.isfinite(value):
                raise ValueError(non_finite_message(f"hydrogel.{name}", value, field_range(GelSpec, name),
                                                    field_unit(GelSpec, name)))
        if self.chambers is not None:
            self._check_chambers()
        elif self.chamber_wall_thickness is not None or self.strain_limit_position is not None:
            name = "chamber_wall_thickness" if self.chamber_wall_thickness is not None else "strain_limit_position"
            raise ValueError(f"{name}: only with chambers (a single-chamber design has no shared wall and its "
                             f"strain-limit layer on the -x face; got {name} with no [[chambers]])")
        d, c = self.particle_diameter, self.clearance
        if not c < d / 4.0:
            raise ValueError(
                f"clearance: must be < particle_diameter/4 = {_g(d / 4.0)} mm (got {_g(c)} mm)"
            )
        if self.cavity_depth is not None and self.dimension != 3:
            raise ValueError(
                f"cavity_depth: only with dimension = 3 (got cavity_depth {_g(self.cavity_depth)} mm "
                f"with dimension {self.dimension})"
            )
        if self.strain_limit_width is not None:
            if self.dimension != 3:
                raise ValueError(
                    f"strain_limit_width: only with dimension = 3 (2D is plane strain: the layer spans the whole "
                    f"depth; got strain_limit_width {_g(self.strain_limit_width)} mm with dimension {self.dimension})"
                )
            face = self.resolved_cavity_depth + 2.0 * self.side_wall_thickness
            if self.strain_limit_width > face * (1.0 + _REL_TOL):
                raise ValueError(
                    f"strain_limit_width: must be in (0, {_g(face)}] mm, the -x face's width cavity_depth + "
                    f"2 side_wall_thickness (got {_g(self.strain_limit_width)} mm)"
                )
        self._check_helix()
        if not self.mesh.symmetry and self.dimension != 3:
            raise ValueError(
                f"mesh.symmetry: false only with dimension = 3 (2D has no depth to cut; got dimension {self.dimension})"
            )
        fits = [("cavity_width", self.particles_per_layer, self.resolved_cavity_width),
                ("cavity_length", self.particle_layers, self.resolved_cavity_length)]
        if self.chambers is not None:  # each chamber's particles are checked in _check_chambers
            fits = []
        if self.dimension == 3:
            fits.append(("cavity_depth", 1, self.resolved_cavity_depth))
        for name, count, size in fits:
            need = count * d + (count + 1) * c
            if need > size * (1.0 + _REL_TOL):
                raise ValueError(
                    f"{name}: the particles do not fit: {count} x {_g(d)} mm + {count + 1} x {_g(c)} mm "
                    f"clearance = {_g(need)} mm > {name} {_g(size)} mm; need {name} >= {_g(need)} mm"
                )
        h = self.mesh_size
        if h > d / 4.0:
            raise ValueError(
                f"mesh.size: must be <= particle_diameter/4 = {_g(d / 4.0)} mm so that about 12 quadratic "
                f"edges or more go round a particle (got {_g(h)} mm)"
            )
        if h > self.resolved_cavity_length:
            raise ValueError(
                f"mesh.size: must be <= cavity_length {_g(self.resolved_cavity_length)} mm (got {_g(h)} mm)"
            )
        if self.strain_limit_width is not None and self.strain_limit_width / 2.0 < MIN_WALL_PER_MESH * h:
            need = 2.0 * MIN_WALL_PER_MESH * h
            raise ValueError(
                f"strain_limit_width: too narrow for mesh.size {_g(h)} mm: must be >= {_g(need)} mm (each half of "
                f"the strip >= mesh.size/4), else its elements are slivers (got {_g(self.strain_limit_width)} mm)"
            )
        walls = [("side_wall_thickness", self.side_wall_thickness, 1.0),
                 ("end_wall_thickness", self.end_wall_thickness, 1.0),
                 ("strain_limit_thickness", self.strain_limit_thickness, 0.5)]
        for name, t, share in walls:
            if share * t < MIN_WALL_PER_MESH * h:
                need = MIN_WALL_PER_MESH * h / share
                halves = " (it is meshed in two halves, each >= mesh.size/4)" if share != 1.0 else ""
                raise ValueError(
                    f"{name}: too thin for mesh.size {_g(h)} mm: must be >= {_g(need)} mm{halves}, else "
                    f"its elements are slivers (got {_g(t)} mm); use a thicker wall or a smaller mesh.size"
                )
        n = self.estimated_elements()
        if not n <= MAX_ELEMENTS:
            dims = f"{_g(self.width)} x {_g(self.length)} mm" + (
                f" x {_g(self.resolved_cavity_depth + 2.0 * self.side_wall_thickness)} mm" if self.dimension == 3 else "")
            raise ValueError(
                f"mesh.size: the mesh would have about {n:.2g} elements ({dims} at mesh.size {_g(h)} mm); "
                f"at most {MAX_ELEMENTS:.0e} are built: use a larger mesh.size or a smaller actuator"
            )
        size = max(self.width, self.length)
        if c < MIN_CLEARANCE_PER_SIZE * size:
            raise ValueError(
                f"clearance: must be >= 1e-6 x the actuator's larger size {_g(size)} mm = "
                f"{_g(MIN_CLEARANCE_PER_SIZE * size)} mm: a smaller gap is lost in the round-off of the "
                f"geometry (got {_g(c)} mm)"
            )
        return self


# -------------------------------------------------------------------- reading


def with_replicas(design: Design, count: int) -> Design:
    """The design with ``replicas.count`` set to ``count`` (1 .. MAX_REPLICAS); DesignError
    naming ``replicas.count`` outside the range or when the design is one replica (index > 0)."""
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_REPLICAS:
        raise DesignError(f"replicas.count: must be an integer in [1, {MAX_REPLICAS}] (got {count!r})")
    if count > 1 and design.replicas.index > 0:
        raise DesignError(f"replicas.index: the design is replica {design.replicas.index} of a set; "
                          "replicas of it need index 0 (got index > 0 with count > 1)")
    return design.model_copy(update={"replicas": design.replicas.model_copy(update={"count": count})})


def default_design() -> Design:
    """The default design (docs/actuator.md, "Design"): d 16 mm, PL 5, clearance 0.1 mm, L = 88.6 mm.

    Returns
    -------
    Design
    """
    return Design()


def design_from_dict(data: dict) -> Design:
    """A validated Design from plain data (e.g. parsed TOML).

    Types are checked strictly (TOML values are typed): an integer where a number is expected
    is accepted, a string or a float where an integer is expected is not.

    Parameters
    ----------
    data : dict
        The design's keys, nested tables as dicts; lengths [mm], temperatures [K], chemical
        potentials [k_B T], moduli [MPa].

    Returns
    -------
    Design

    Raises
    ------
    DesignError
        One line naming the field and its allowed range.
    """
    if not isinstance(data, dict):
        raise DesignError(f"design: expected a table of keys, got {type(data).__name__}")
    try:
        return Design.model_validate(data, strict=True)
    except ValidationError as err:
        raise DesignError(explain_error(err, Design)) from None


def load_design(path: str | os.PathLike) -> Design:
    """Read a design TOML file.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    Design

    Raises
    ------
    DesignError
        Naming the file, for a missing or invalid one.
    """
    path = Path(path)
    data = read_toml(path, "design", DesignError)
    try:
        return design_from_dict(data)
    except DesignError as err:
        raise DesignError(f"{path}: {err}") from None


def _parse_value(text: str):
    try:
        return tomllib.loads("v = " + text)["v"]
    except tomllib.TOMLDecodeError:
        return text.strip()


def merge_value(into: dict, key: list[str], value) -> None:
    """Set the nested field ``key`` (its path of names) of the dict ``into`` to ``value``,
    merging a dict into a dict already there (a design override)."""
    for name in key[:-1]:
        into = into.setdefault(name, {})
    old = into.get(key[-1])
    if isinstance(old, dict) and isinstance(value, dict):
        merged = dict(old)
        for k, v in value.items():
            merge_value(merged, [k], v)
        into[key[-1]] = merged
    else:
        into[key[-1]] = value


def apply_overrides(design: Design, overrides: list[str]) -> Design:
    """The design with each 'dotted.key=value' override applied (e.g. 'stimulus.temperature=295').

    A value is read as a TOML value, else as a plain string ('stimulus.path=linear'). Overrides
    merge into the unresolved design (derived cavity sizes follow a new particle_diameter) and the
    result is validated as a whole.

    Parameters
    ----------
    design : Design
        The design to start from.
    overrides : list of str
        'dotted.key=value' items, each in the field's unit.

    Returns
    -------
    Design

    Raises
    ------
    DesignError
        Naming the override.
    """
    data = design.model_dump(exclude_none=True)
    applied: list[tuple[str, str]] = []
    for item in overrides:
        if not isinstance(item, str) or "=" not in item:
            raise DesignError(f"--set {item}: expected key=value, e.g. stimulus.temperature=295")
        key, _, text = item.partition("=")
        key = key.strip()
        parts = key.split(".")
        if not key or any(not p for p in parts):
            raise DesignError(f"--set {item}: expected key=value with a dotted key, e.g. stimulus.temperature=295")
        for i in range(len(parts)):
            model = submodel(Design, parts[:i])
            if model is None:
                raise DesignError(f"--set {item}: {'.'.join(parts[:i])} is not a table")
            if parts[i] not in model.model_fields:
                raise DesignError(
                    f"--set {item}: unknown key {key} (allowed: {', '.join(model.model_fields)})"
                )
        merge_value(data, parts, _parse_value(text))
        applied.append((key, item))
    try:
        return design_from_dict(data)
    except DesignError as err:
        msg = str(err)
        blamed = [item for key, item in applied if msg.startswith(key + ":") or msg.startswith(key + ".")]
        items = blamed or [item for _, item in applied]
        prefix = ", ".join(f"--set {i}" for i in items)
        raise DesignError(f"{prefix}: {msg}" if prefix else msg) from None


# -------------------------------------------------------------------- writing

_HEADER = """\
hydrojam actuator design: PNIPAM hydrogel particles jammed in an elastomer chamber with a
strain-limit layer (a soft bending actuator).
Units: length mm, stress MPa, temperature K, chemical potential kT (k_B T).
Run it with:   hydrojam run design.toml -o out
Every key is optional (a missing key takes its default); a commented-out key is derived."""

_DERIVED = {
    "cavity_width": "resolved_cavity_width",
    "cavity_length": "resolved_cavity_length",
    "cavity_depth": "resolved_cavity_depth",
    "size": "mesh_size",  # [mesh]
}


#: an example for optional keys left out (written commented out)
_EXAMPLES = {"schedule": "[[0, 300], [60, 275], [7200, 275]]",
             "friction_slip": "0.0008  # 1% of dhat = 0.8 clearance, at the default clearance",
             "strain_limit_width": "8.0  # 3D only: a strip 8 mm wide centred on the -x face",
             "strain_limit_helix_deg": "30.0  # 3D full model, with strain_limit_width: the strip wound at 30 deg"}


def toml_value(value) -> str:
    """``value`` written as a TOML value (the right-hand side of ``key = value``)."""
    return tomli_w.dumps({"v": value})[len("v = "):].rstrip("\n")


_NBSP = "\0"  # keeps an interval such as "(0, inf)" on one comment line


def _comment(text: str) -> list[str]:
    return [f"# {line.replace(_NBSP, ' ')}" for line in textwrap.wrap(text, 96)]


def _allowed(model: type[BaseModel], name: str) -> str:
    info = model.model_fields[name]
    ann = info.annotation
    if typing.get_origin(ann) is Literal:
        return "allowed: " + ", ".join(toml_value(v) for v in typing.get_args(ann))
    rng = field_range(model, name)
    return f"allowed {rng.replace(' ', _NBSP)}" if rng else ""


def _field_lines(model: BaseModel, comments: bool, owner: Design | None) -> list[str]:
    cls = type(model)
    lines: list[str] = []
    for name, info in cls.model_fields.items():
        if submodel(cls, [name]) is not None:
            continue
        value = getattr(model, name)
        if comments:
            parts = [info.description or name]
            allowed = _allowed(cls, name)
            if allowed:
                parts.append(allowed)
            if info.default is not None:
                parts.append(f"default {toml_value(info.default)}")
            lines += _comment("; ".join(parts))
        if value is None:
            if comments and owner is not None and name in _DERIVED:
                lines += [f"# {name} = {toml_value(getattr(owner, _DERIVED[name]))}", ""]
            elif comments and name in _EXAMPLES:
                lines += [f"# {name} = {_EXAMPLES[name]}", ""]
            continue
        lines.append(f"{name} = {toml_value(value)}")
        if comments:
            lines.append("")
    return lines


def design_to_toml(design: Design, comments: bool = True) -> str:
    """The design as a TOML document.

    Round-trips: ``design_from_dict(tomllib.loads(design_to_toml(d))) == d``.

    Parameters
    ----------
    design : Design
        The design.
    comments : bool, optional
        Every key with its description, unit, allowed range and default above it, and derived
        (None) keys commented out.

    Returns
    -------
    str
        The TOML text.
    """
    lines: list[str] = []
    if comments:
        lines += [f"# {line}" if line else "#" for line in _HEADER.splitlines()] + [""]
    lines += _field_lines(design, comments, design)
    for name, info in Design.model_fields.items():
        if submodel(Design, [name]) is None or name == "chambers":
            continue
        if lines and lines[-1] != "":
            lines.append("")
        if comments:
            lines += _comment(info.description or name)
        lines.append(f"[{name}]")
        lines += _field_lines(getattr(design, name), comments, design if name == "mesh" else None)
    if comments and design.chambers is None:
        lines += ([""] if lines and lines[-1] != "" else []) + _comment(Design.model_fields["chambers"].description) + [
            "# [[chambers]]", "# [[chambers]]", "# temperature = 295.0", "# [chambers.hydrogel]",
            "# A0 = -12.4974  # PNIPAM's chi(T) shifted 10 K down (docs/chambers.md)", "# A1 = 17.351"]
    for k, chamber in enumerate(design.chambers or ()):
        if lines and lines[-1] != "":
            lines.append("")
        if comments and k == 0:
            lines += _comment(Design.model_fields["chambers"].description)
        lines.append("[[chambers]]")
        lines += [f"{key} = {toml_value(value)}" for key, value in chamber.model_dump(exclude_none=True).items()
                  if key != "hydrogel"]
        if chamber.hydrogel is not None:
            lines += ["", "[chambers.hydrogel]"]
            lines += [f"{key} = {toml_value(value)}" for key, value in chamber.hydrogel.model_dump().items()]
    while lines and lines[-1] == "":
        lines.pop()
    return "\n".join(lines) + "\n"


def write_design(path: str | os.PathLike, design: Design, comments: bool = True) -> None:
    """Write the design as (commented) TOML atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    design : Design
        The design.
    comments : bool, optional
        As for :func:`design_to_toml`.
    """
    write_text_atomic(path, design_to_toml(design, comments))
