"""Hyperelastic energy densities: the PNIPAM hydrogel and the elastomers (docs/model.md).

A material maps deformation gradients ``F`` of shape ``(..., d, d)`` (d = 2: plane strain, d = 3)
to the stored energy per reference volume ``W`` [MPa = mJ/mm^3], the first Piola-Kirchhoff stress
``P = dW/dF`` [MPa] and the tangent ``A = dP/dF`` [MPa], shape ``(..., d, d, d, d)`` indexed
``A[i, J, k, L] = d P_iJ / d F_kL``. Plane strain means ``F_3D = diag(F, 1)``.

Inadmissible states (``det F <= 0``; a gel holding less than zero water, ``J_dry <= 1``) have
``W = +inf`` with ``P`` and ``A`` set to zero there: a solver rejects them through the energy and
never sees a NaN.

All materials here are isotropic functions of two invariants, ``I1 = tr(C)`` and ``J = det F`` of
a possibly pre-stretched gradient ``c^(1/2) F`` (``c = lambda0^2`` for the gel, whose energy is
defined per dry volume, ``c = 1`` otherwise), so one kernel differentiates them all.

Compiled path: besides the numpy ``evaluate``, each material here has ``evaluate_compiled(F,
order)``, the same W, P, A from one numba-compiled loop over the points (the same formulas, so the
results differ only in round-off). It is optional: the finite-element layer uses it where a
material has it and ``evaluate`` otherwise. numba is imported on its first call only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field

KT_OVER_NU_MPA = 40.0
"""Stress unit of the gel model, k_B T / nu [MPa] (paper: 4e7 Pa)."""

#: water is liquid between these temperatures [K] (at 1 atm): the range of every temperature
WATER_RANGE_K = (273.15, 373.15)

# Cai & Suo (2011) fit of chi(T, J) for PNIPAM; the paper rounds B0 to 0.0449.
A0_DEFAULT = -12.947
B0_DEFAULT = 0.04496
A1_DEFAULT = 17.92
B1_DEFAULT = -0.0569


@dataclass(frozen=True)
class MaterialResponse:
    """Energy density, stress and tangent of a material at many points.

    Parameters
    ----------
    energy : ndarray, shape (...)
        Stored energy per reference volume W [MPa]; +inf where inadmissible.
    stress : ndarray, shape (..., d, d)
        First Piola-Kirchhoff stress P = dW/dF [MPa].
    tangent : ndarray, shape (..., d, d, d, d) or None
        Tangent A = dP/dF [MPa], ``A[..., i, J, k, L] = dP_iJ/dF_kL``; None where not asked for.
    """

    energy: np.ndarray
    stress: np.ndarray
    tangent: np.ndarray | None


@runtime_checkable
class Material(Protocol):
    """What the finite-element layer needs from a material.

    Optional, outside the protocol: ``evaluate_compiled(F, order)`` (the compiled path, see the
    module docstring).
    """

    @property
    def shear_modulus_ref(self) -> float:
        """Small-strain shear modulus about the reference configuration [MPa] (for scales)."""

    def energy(self, F: np.ndarray) -> np.ndarray:
        """Stored energy per reference volume.

        Parameters
        ----------
        F : ndarray, shape (..., d, d)
            Deformation gradients [-].

        Returns
        -------
        ndarray, shape (...)
            W(F) [MPa]; +inf where inadmissible.
        """

    def evaluate(self, F: np.ndarray, tangent: bool = True) -> MaterialResponse:
        """Energy, stress and (optionally) tangent at every F.

        Parameters
        ----------
        F : ndarray, shape (..., d, d)
            Deformation gradients [-].
        tangent : bool, optional
            Whether to compute dP/dF too.

        Returns
        -------
        MaterialResponse
            W [MPa], P [MPa] and dP/dF [MPa] (None unless ``tangent``).
        """


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


# --------------------------------------------------------------------------------------------
# The shared kernel


def _det_and_inverse(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """det F and F^-1 for stacks of 2x2 or 3x3 matrices (closed form: faster than LAPACK here)."""
    d = F.shape[-1]
    if d == 2:
        a, b, c, e = F[..., 0, 0], F[..., 0, 1], F[..., 1, 0], F[..., 1, 1]
        det = a * e - b * c
        cof = np.stack([np.stack([e, -c], -1), np.stack([-b, a], -1)], -2)  # cofactor matrix
    elif d == 3:
        c0 = np.cross(F[..., 1, :], F[..., 2, :])
        c1 = np.cross(F[..., 2, :], F[..., 0, :])
        c2 = np.cross(F[..., 0, :], F[..., 1, :])
        cof = np.stack([c0, c1, c2], -2)  # rows of the cofactor matrix
        det = np.einsum("...j,...j->...", F[..., 0, :], c0)
    else:
        raise ValueError(f"deformation gradients must be 2x2 or 3x3, got {d}x{d}")
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.swapaxes(cof, -1, -2) / det[..., None, None]
    return det, inv


class _InvariantMaterial:
    """Mixin: W(F) = scale * psi(I1, J) with I1 = c (|F|^2 + 3 - d), J = c^(3/2) det F.

    Subclasses provide ``_psi(I1, J)`` returning psi and its first and second partial derivatives
    (psi, psi_1, psi_J, psi_11, psi_1J, psi_JJ), ``_prestretch_sq`` (c), ``_scale`` and
    ``_admissible(J)``.
    """

    _prestretch_sq: float = 1.0
    _scale: float = 1.0
    _energy_offset: float = 0.0

    def _admissible(self, J: np.ndarray) -> np.ndarray:
        return J > 0.0

    def _psi(self, I1, J, order: int):  # pragma: no cover - abstract
        raise NotImplementedError

    def _invariants(self, F: np.ndarray):
        F = np.asarray(F, dtype=float)
        d = F.shape[-1]
        c = self._prestretch_sq
        detF, Finv = _det_and_inverse(F)
        I1 = c * (np.einsum("...ij,...ij->...", F, F) + (3 - d))
        J = c**1.5 * detF
        ok = (detF > 0.0) & self._admissible(J)
        return F, d, c, Finv, I1, J, ok

    def energy(self, F: np.ndarray) -> np.ndarray:
        """Stored energy per reference volume.

        Parameters
        ----------
        F : ndarray, shape (..., d, d)
            Deformation gradients [-] (d = 2: plane strain, or 3).

        Returns
        -------
        ndarray, shape (...)
            W [MPa]; +inf where inadmissible.
        """
        F, _, _, _, I1, J, ok = self._invariants(F)
        Js = np.where(ok, J, 2.0)
        psi = self._psi(I1, Js, 0)[0]
        return np.where(ok, self._scale * psi - self._energy_offset, np.inf)

    def evaluate(self, F: np.ndarray, tangent: bool = True) -> MaterialResponse:
        """Energy, first Piola-Kirchhoff stress and tangent at every F.

        Parameters
        ----------
        F : ndarray, shape (..., d, d)
            Deformation gradients [-] (d = 2: plane strain, or 3).
        tangent : bool, optional
            Whether to compute A = dP/dF too.

        Returns
        -------
        MaterialResponse
            W [MPa], P = dW/dF [MPa] and A = dP/dF [MPa] (``A[..., i, J, k, L] = dP_iJ/dF_kL``; None
            unless ``tangent``); +inf energy and zero P, A where inadmissible.
        """
        F, d, c, Finv, I1, J, ok = self._invariants(F)
        Js = np.where(ok, J, 2.0)
        psi, p1, pJ, p11, p1J, pJJ = self._psi(I1, Js, 2 if tangent else 1)
        s = self._scale
        G = np.swapaxes(np.where(ok[..., None, None], Finv, 0.0), -1, -2)  # F^-T
        dI1 = 2.0 * c * F
        dJ = Js[..., None, None] * G
        W = np.where(ok, s * psi - self._energy_offset, np.inf)
        P = s * (p1[..., None, None] * dI1 + pJ[..., None, None] * dJ)
        P = np.where(ok[..., None, None], P, 0.0)
        A = None
        if tangent:
            eye = np.eye(d)
            A = (
                p11[..., None, None, None, None] * np.einsum("...ij,...kl->...ijkl", dI1, dI1)
                + p1J[..., None, None, None, None]
                * (np.einsum("...ij,...kl->...ijkl", dI1, dJ) + np.einsum("...ij,...kl->...ijkl", dJ, dI1))
                + pJJ[..., None, None, None, None] * np.einsum("...ij,...kl->...ijkl", dJ, dJ)
                + (2.0 * c * p1)[..., None, None, None, None] * np.einsum("ik,jl->ijkl", eye, eye)
                + (pJ * Js)[..., None, None, None, None]
                * (np.einsum("...ij,...kl->...ijkl", G, G) - np.einsum("...il,...kj->...ijkl", G, G))
            )
            A = np.where(ok[..., None, None, None, None], s * A, 0.0)
        return MaterialResponse(W, P, A)


    # Compiled path: the material's constants as one float array for _compiled_batch.
    _KIND_YEOH = 0
    _KIND_GEL = 1

    def _compiled_constants(self) -> NDArray[np.float64]:  # pragma: no cover - abstract
        raise NotImplementedError

    def evaluate_compiled(self, F: np.ndarray, order: int = 2) -> MaterialResponse:
        """``evaluate`` by a compiled loop over the points.

        Same formulas as ``evaluate``, so equal to it up to round-off; +inf / zeros at inadmissible
        states alike.

        Parameters
        ----------
        F : ndarray, shape (..., d, d)
            Deformation gradients [-] (d = 2 or 3).
        order : {0, 1, 2}, optional
            0: W only; 1: with P; 2: with A.

        Returns
        -------
        MaterialResponse
            W [MPa], P [MPa] (order >= 1) and A [MPa] (order 2); P and A are None where not asked for.

        Raises
        ------
        ValueError
            If ``order`` is not 0, 1 or 2, or F is not a stack of 2x2 or 3x3 matrices.
        """
        if order not in (0, 1, 2):
            raise ValueError(f"order must be 0, 1 or 2 (got {order})")
        F = np.asarray(F, dtype=float)
        shape, d = F.shape[:-2], F.shape[-1]
        if F.shape[-2] != d or d not in (2, 3):
            raise ValueError(f"deformation gradients must be 2x2 or 3x3, got {F.shape[-2:]}")
        F = np.ascontiguousarray(F.reshape(-1, d, d))
        W, P, A = _compiled_batch()(F, self._compiled_constants(), order, (0,) * d)
        return MaterialResponse(
            W.reshape(shape),
            P.reshape(shape + (d, d)) if order >= 1 else None,
            A.reshape(shape + (d, d, d, d)) if order >= 2 else None,
        )


def _invariant_batch(F, k, order, dims):  # pragma: no cover - compiled by numba (coverage cannot see it)
    """W, P, A at the points F (N, d, d) of the material with constants k (see _compiled_constants):
    k = [kind, c, scale, energy offset, J_min, then 4 of the kind's own]. The numpy path
    (_InvariantMaterial.evaluate, _yeoh_psi, gel_psi) written out per point. ``dims`` is any
    tuple of d integers: its length is known when compiling, so the loops over d are unrolled."""
    N, d = F.shape[0], len(dims)
    kind, c, s, off, Jmin = k[0], k[1], k[2], k[3], k[4]
    c15 = c**1.5
    W = np.empty(N)
    P = np.zeros((N if order >= 1 else 0, d, d))
    A = np.zeros((N if order >= 2 else 0, d, d, d, d))
    G = np.empty((d, d))
    for n in range(N):
        f = F[n]
        if d == 2:
            det = f[0, 0] * f[1, 1] - f[0, 1] * f[1, 0]
            G[0, 0], G[0, 1], G[1, 0], G[1, 1] = f[1, 1], -f[1, 0], -f[0, 1], f[0, 0]
        else:
            for r in range(3):
                r1, r2 = (r + 1) % 3, (r + 2) % 3  # cofactor row r = F[r1] x F[r2]
                G[r, 0] = f[r1, 1] * f[r2, 2] - f[r1, 2] * f[r2, 1]
                G[r, 1] = f[r1, 2] * f[r2, 0] - f[r1, 0] * f[r2, 2]
                G[r, 2] = f[r1, 0] * f[r2, 1] - f[r1, 1] * f[r2, 0]
            det = f[0, 0] * G[0, 0] + f[0, 1] * G[0, 1] + f[0, 2] * G[0, 2]
        J = c15 * det
        if not (det > 0.0 and J > Jmin):
            W[n] = np.inf  # P, A stay zero
            continue
        ff = 0.0
        for i in range(d):
            for j in range(d):
                ff += f[i, j] * f[i, j]
        I1 = c * (ff + (3 - d))
        p11 = p1J = 0.0
        if kind == 0.0:  # Yeoh (neo-Hookean: C20 = C30 = 0)
            C1, C2, C3, K = k[5], k[6], k[7], k[8]
            a = J ** (-2.0 / 3.0)
            Ib = a * I1
            x = Ib - 3.0
            psi = C1 * x + C2 * x**2 + C3 * x**3 + 0.5 * K * (J - 1.0) ** 2
            U1 = C1 + 2.0 * C2 * x + 3.0 * C3 * x**2
            U2 = 2.0 * C2 + 6.0 * C3 * x
            dIb_dJ = -2.0 / 3.0 * Ib / J
            p1 = U1 * a
            pJ = U1 * dIb_dJ + K * (J - 1.0)
            p11 = U2 * a * a
            p1J = U2 * a * dIb_dJ + U1 * (-2.0 / 3.0) * a / J
            pJJ = U2 * dIb_dJ**2 + U1 * (10.0 / 9.0) * Ib / J**2 + K
        else:  # the gel, per dry volume
            nn, chi0, chi1, mu = k[5], k[6], k[7], k[8]
            iJ = 1.0 / J
            l1 = np.log1p(-iJ)
            psi = (0.5 * nn * (I1 - 3.0 - 2.0 * np.log(J)) + (J - 1.0) * l1 + (chi0 + chi1 * iJ) * (1.0 - iJ)
                   - mu * (J - 1.0))
            g = l1 + iJ + (chi0 - chi1) * iJ**2 + 2.0 * chi1 * iJ**3 - mu
            p1 = 0.5 * nn
            pJ = -nn * iJ + g
            pJJ = nn * iJ**2 + iJ**2 / (J - 1.0) - 2.0 * (chi0 - chi1) * iJ**3 - 6.0 * chi1 * iJ**4
        W[n] = s * psi - off
        if order == 0:
            continue
        for i in range(d):
            for j in range(d):
                G[i, j] /= det  # now F^-T
        for i in range(d):
            for j in range(d):
                P[n, i, j] = s * (p1 * (2.0 * c * f[i, j]) + pJ * (J * G[i, j]))
        if order == 1:
            continue
        for i in range(d):
            for j in range(d):
                a1, aJ = 2.0 * c * f[i, j], J * G[i, j]
                for kk in range(d):
                    for ll in range(d):
                        b1, bJ = 2.0 * c * f[kk, ll], J * G[kk, ll]
                        v = p11 * a1 * b1 + p1J * (a1 * bJ + aJ * b1) + pJJ * aJ * bJ
                        v += pJ * J * (G[i, j] * G[kk, ll] - G[i, ll] * G[kk, j])
                        if i == kk and j == ll:
                            v += 2.0 * c * p1
                        A[n, i, j, kk, ll] = s * v
    return W, P, A


_COMPILED = []


def _compiled_batch():
    """The numba-compiled _invariant_batch (compiled on first use, cached on disk)."""
    if not _COMPILED:
        import numba

        _COMPILED.append(numba.njit(cache=True)(_invariant_batch))
    return _COMPILED[0]


# --------------------------------------------------------------------------------------------
# Elastomers


def _yeoh_psi(I1, J, coeffs, bulk, order):
    """Abaqus-form Yeoh: sum_i C_i0 (I1bar - 3)^i + K/2 (J - 1)^2, I1bar = J^(-2/3) I1."""
    a = J ** (-2.0 / 3.0)
    Ib = a * I1
    x = Ib - 3.0
    U = sum(C * x ** (i + 1) for i, C in enumerate(coeffs))
    psi = U + 0.5 * bulk * (J - 1.0) ** 2
    if order == 0:
        return (psi,)
    U1 = sum((i + 1) * C * x**i for i, C in enumerate(coeffs))
    U2 = sum((i + 1) * i * C * x ** (i - 1) for i, C in enumerate(coeffs) if i > 0)
    U2 = U2 + 0.0 * x
    dIb_dJ = -2.0 / 3.0 * Ib / J
    p1 = U1 * a
    pJ = U1 * dIb_dJ + bulk * (J - 1.0)
    if order == 1:
        z = 0.0 * x
        return psi, p1, pJ, z, z, z
    p11 = U2 * a * a
    p1J = U2 * a * dIb_dJ + U1 * (-2.0 / 3.0) * a / J
    pJJ = U2 * dIb_dJ**2 + U1 * (10.0 / 9.0) * Ib / J**2 + bulk
    return psi, p1, pJ, p11, p1J, pJJ


def bulk_modulus(shear_modulus: float, poisson_ratio: float) -> float:
    """Small-strain bulk modulus K = 2G(1 + nu) / (3(1 - 2nu)).

    Parameters
    ----------
    shear_modulus : float
        Small-strain shear modulus G [MPa].
    poisson_ratio : float
        Small-strain Poisson's ratio nu [-], below 0.5.

    Returns
    -------
    float
        K [MPa].
    """
    return 2.0 * shear_modulus * (1.0 + poisson_ratio) / (3.0 * (1.0 - 2.0 * poisson_ratio))


class NeoHookean(_Frozen, _InvariantMaterial):
    """Compressible neo-Hookean solid (Abaqus form): W = G/2 (I1bar - 3) + K/2 (J - 1)^2.

    Defaults: Ecoflex 00-30, G = 0.023 MPa, Poisson's ratio 0.45 (K derived).

    Parameters
    ----------
    shear_modulus : float, optional
        Small-strain shear modulus G [MPa].
    poisson_ratio : float, optional
        Small-strain Poisson's ratio [-], in [0, 0.5).
    """

    shear_modulus: float = Field(0.023, gt=0, description="small-strain shear modulus G [MPa]")
    poisson_ratio: float = Field(0.45, ge=0, lt=0.5, description="small-strain Poisson's ratio [-]")

    @property
    def shear_modulus_ref(self) -> float:
        return self.shear_modulus

    @property
    def bulk_modulus(self) -> float:
        """K [MPa], derived from G and the Poisson's ratio."""
        return bulk_modulus(self.shear_modulus, self.poisson_ratio)

    def _psi(self, I1, J, order):
        return _yeoh_psi(I1, J, (0.5 * self.shear_modulus,), self.bulk_modulus, order)

    def _compiled_constants(self):
        return np.array([self._KIND_YEOH, 1.0, 1.0, 0.0, 0.0, 0.5 * self.shear_modulus, 0.0, 0.0, self.bulk_modulus])


class Yeoh(_Frozen, _InvariantMaterial):
    """Compressible Yeoh solid (Abaqus form): W = sum_i C_i0 (I1bar - 3)^i + K/2 (J - 1)^2.

    The initial shear modulus is 2 C10; K follows from it and the Poisson's ratio. Defaults
    reduce to the Ecoflex 00-30 neo-Hookean (C10 = G/2); give C20, C30 from a fit for
    large-strain stiffening.

    Parameters
    ----------
    c10, c20, c30 : float, optional
        Coefficients C10 (> 0), C20, C30 [MPa].
    poisson_ratio : float, optional
        Small-strain Poisson's ratio [-], in [0, 0.5).
    """

    c10: float = Field(0.0115, gt=0, description="C10 [MPa]")
    c20: float = Field(0.0, description="C20 [MPa]")
    c30: float = Field(0.0, description="C30 [MPa]")
    poisson_ratio: float = Field(0.45, ge=0, lt=0.5, description="small-strain Poisson's ratio [-]")

    @property
    def shear_modulus_ref(self) -> float:
        return 2.0 * self.c10

    @property
    def bulk_modulus(self) -> float:
        """K [MPa], derived from 2 C10 and the Poisson's ratio."""
        return bulk_modulus(2.0 * self.c10, self.poisson_ratio)

    def _psi(self, I1, J, order):
        return _yeoh_psi(I1, J, (self.c10, self.c20, self.c30), self.bulk_modulus, order)

    def _compiled_constants(self):
        return np.array([self._KIND_YEOH, 1.0, 1.0, 0.0, 0.0, self.c10, self.c20, self.c30, self.bulk_modulus])


# --------------------------------------------------------------------------------------------
# PNIPAM hydrogel


class HydrogelParams(_Frozen):
    """Constants of the temperature-sensitive gel (docs/model.md, "Hydrogel"); the stimulus is separate.

    Symbols: n = N nu (``n``), lambda0 (``lambda0``), T0 (``T0``), chi(T, J) = A0 + B0 T +
    (A1 + B1 T)/J. The defaults are the paper's PNIPAM gel; the stress unit is k_B T / nu = 40 MPa.

    Examples
    --------
    >>> from hydrojam import HydrogelParams
    >>> p = HydrogelParams()
    >>> round(p.mu0, 4)          # the paper's reference chemical potential [k_B T]
    -0.0343
    """

    n: float = Field(0.01, gt=0, le=1.0, description="N nu: polymer chains per solvent-molecule volume [-]")
    lambda0: float = Field(1.5, gt=1.0, le=10.0, description="as-prepared free-swelling stretch lambda0 [-]")
    T0: float = Field(300.0, ge=WATER_RANGE_K[0], le=WATER_RANGE_K[1], description="temperature of the as-prepared state T0 [K]")
    A0: float = Field(A0_DEFAULT, description="chi coefficient A0 [-]")
    B0: float = Field(B0_DEFAULT, description="chi coefficient B0 [1/K]")
    A1: float = Field(A1_DEFAULT, description="chi coefficient A1 [-]")
    B1: float = Field(B1_DEFAULT, description="chi coefficient B1 [1/K]")
    kT_over_nu: float = Field(KT_OVER_NU_MPA, gt=0, description="stress unit k_B T / nu [MPa]")

    def chi_coefficients(self, T: float) -> tuple[float, float]:
        """Coefficients of chi(T, J) = chi0 + chi1 / J at one temperature.

        Parameters
        ----------
        T : float
            Temperature [K].

        Returns
        -------
        chi0, chi1 : float
            A0 + B0 T and A1 + B1 T [-].
        """
        return self.A0 + self.B0 * T, self.A1 + self.B1 * T

    @property
    def mu0(self) -> float:
        """Chemical potential mu0 [k_B T] at which the as-prepared state (lambda0, T0) is stress-free."""
        return reference_chemical_potential(self)


def _mixing_g(chi0, chi1, mu, iJ, l1):
    """g from 1/J (``iJ``) and ln(1 - 1/J) (``l1``): the one formula of the mixing term."""
    return l1 + iJ + (chi0 - chi1) * iJ**2 + 2.0 * chi1 * iJ**3 - mu


def mixing_g(params: HydrogelParams, J, mu: float, T: float):
    """g(J) = ln(1 - 1/J) + 1/J + (chi0 - chi1)/J^2 + 2 chi1/J^3 - mu [k_B T / nu] (docs/model.md,
    "Swelling analysis"): dw/dJ without the network term, J the volume ratio to the dry network."""
    chi0, chi1 = params.chi_coefficients(T)
    iJ = 1.0 / np.asarray(J, dtype=float)
    return _mixing_g(chi0, chi1, mu, iJ, np.log1p(-iJ))


def nominal_stresses(params: HydrogelParams, stretches, mu: float, T: float) -> np.ndarray:
    """Principal nominal stresses of the gel, s_i = n (l_i - 1/l_i) + (J/l_i) g(J), dry reference.

    Parameters
    ----------
    params : HydrogelParams
        The gel's constants.
    stretches : array_like, shape (..., 3)
        Principal stretches l_i relative to the dry network [-].
    mu : float
        Chemical potential of the solvent [k_B T].
    T : float
        Temperature [K].

    Returns
    -------
    ndarray, shape (..., 3)
        s_i [k_B T / nu].
    """
    lam = np.asarray(stretches, dtype=float)
    J = np.prod(lam, axis=-1, keepdims=True)
    return params.n * (lam - 1.0 / lam) + (J / lam) * mixing_g(params, J, mu, T)


def reference_chemical_potential(params: HydrogelParams) -> float:
    """The chemical potential mu0 at which free swelling to lambda0 at T0 is stress-free.

    Parameters
    ----------
    params : HydrogelParams
        The gel's constants (``lambda0``, ``T0``).

    Returns
    -------
    float
        mu0 [k_B T].
    """
    lam = params.lambda0
    return float(nominal_stresses(params, [lam, lam, lam], 0.0, params.T0)[0] / lam**2)


def gel_psi(params: HydrogelParams, mu: float, T: float, I1, J, order: int = 2):
    """Normalised gel free energy per dry volume w(I1, J; mu, T) [k_B T / nu] and its derivatives.

    w = n/2 (I1 - 3 - 2 ln J) + (J - 1) ln(1 - 1/J) + chi(T, J)(1 - 1/J) - mu (J - 1).
    Returns (w, w_1, w_J, w_11, w_1J, w_JJ) up to ``order``; needs J > 1.
    """
    n = params.n
    chi0, chi1 = params.chi_coefficients(T)
    J = np.asarray(J, dtype=float)
    lnJ = np.log(J)
    l1 = np.log1p(-1.0 / J)
    iJ = 1.0 / J
    w = 0.5 * n * (I1 - 3.0 - 2.0 * lnJ) + (J - 1.0) * l1 + (chi0 + chi1 * iJ) * (1.0 - iJ) - mu * (J - 1.0)
    if order == 0:
        return (w,)
    g = _mixing_g(chi0, chi1, mu, iJ, l1)
    w1 = np.full_like(J, 0.5 * n)
    wJ = -n * iJ + g
    z = np.zeros_like(J)
    if order == 1:
        return w, w1, wJ, z, z, z
    dg = iJ**2 / (J - 1.0) - 2.0 * (chi0 - chi1) * iJ**3 - 6.0 * chi1 * iJ**4
    wJJ = n * iJ**2 + dg
    return w, w1, wJ, z, z, wJJ


class Hydrogel(_InvariantMaterial):
    """PNIPAM gel in contact with solvent at chemical potential mu [k_B T] and temperature T [K].

    The reference configuration is the as-prepared state (free swelling stretch lambda0 of the
    dry network), so W(F) = (k_B T / nu) [w(lambda0 F) - w(lambda0 I)] / lambda0^3 per as-prepared
    volume: the constant shift makes the as-prepared state the zero of energy at every stimulus
    (it does not change any stress). Build one per stimulus with :meth:`at`.

    Parameters
    ----------
    params : HydrogelParams, optional
        The gel's constants (default: the paper's gel).
    mu : float, optional
        Chemical potential of the solvent [k_B T] (default: ``params.mu0``, stress-free as prepared).
    T : float, optional
        Temperature [K] (default: ``params.T0``).

    Examples
    --------
    As prepared the gel is stress-free; in pure water at 275 K, held at its as-prepared size, it
    pushes outward, a compressive first Piola-Kirchhoff stress [MPa]:

    >>> import numpy as np
    >>> from hydrojam import Hydrogel, HydrogelParams
    >>> gel = Hydrogel(HydrogelParams(n=0.01, lambda0=1.5, T0=300.0))
    >>> bool(np.allclose(gel.evaluate(np.eye(3)[None]).stress, 0.0, atol=1e-12))
    True
    >>> cold = gel.at(mu=0.0, T=275.0)
    >>> r = cold.evaluate(np.eye(3)[None])          # energy W, stress P = dW/dF, tangent dP/dF
    >>> bool(r.stress[0, 0, 0] < 0.0)
    True
    >>> round(gel.shear_modulus_ref, 4)              # n (k_B T / nu) / lambda0 [MPa]
    0.2667
    """

    def __init__(self, params: HydrogelParams | None = None, mu: float | None = None, T: float | None = None):
        self.params = params if params is not None else HydrogelParams()
        self.mu = float(self.params.mu0 if mu is None else mu)
        self.T = float(self.params.T0 if T is None else T)
        lam0 = self.params.lambda0
        self._prestretch_sq = lam0**2
        self._scale = self.params.kT_over_nu / lam0**3
        self._energy_offset = float(self._scale * self._psi(3.0 * lam0**2, lam0**3, 0)[0])

    def at(self, mu: float, T: float) -> "Hydrogel":
        """The same gel at another stimulus.

        Parameters
        ----------
        mu : float
            Chemical potential of the solvent [k_B T].
        T : float
            Temperature [K].

        Returns
        -------
        Hydrogel
        """
        return Hydrogel(self.params, mu, T)

    def __repr__(self) -> str:
        return f"Hydrogel(mu={self.mu:.6g}, T={self.T:.6g}, {self.params!r})"

    @property
    def shear_modulus_ref(self) -> float:
        """Network shear modulus in the as-prepared state, n (k_B T / nu) / lambda0 [MPa]."""
        return self.params.n * self.params.kT_over_nu / self.params.lambda0

    def _admissible(self, J):
        return J > 1.0

    def _psi(self, I1, J, order):
        return gel_psi(self.params, self.mu, self.T, I1, J, order)

    def _compiled_constants(self):
        chi0, chi1 = self.params.chi_coefficients(self.T)
        return np.array([self._KIND_GEL, self._prestretch_sq, self._scale, self._energy_offset, 1.0,
                         self.params.n, chi0, chi1, self.mu])

    def swelling_ratio(self, F: np.ndarray) -> np.ndarray:
        """Volume ratio to the dry network, J_dry = lambda0^3 det F.

        Parameters
        ----------
        F : ndarray, shape (..., d, d)
            Deformation gradients from the as-prepared state [-].

        Returns
        -------
        ndarray, shape (...)
            J_dry [-].
        """
        return self.params.lambda0**3 * _det_and_inverse(np.asarray(F, dtype=float))[0]
