"""Material-point swelling of the PNIPAM gel: free and constrained equilibria (docs/model.md, "Swelling analysis").

Stretches here are measured from the *dry* network (as in the paper's equations); ``stretch_rel``
divides by lambda0 to give the stretch from the as-prepared state. Chemical potentials are in
units of k_B T, temperatures in K.

The gel energy is non-convex in J near the volume phase transition, so an equilibrium is found as
the *global* minimiser over the free stretch: every stationary point on a fine logarithmic grid of
J is bracketed and refined, and the lowest-energy minimum is reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from hydrojam.materials.energies import (  # noqa: F401 - nominal_stresses, reference_chemical_potential are part of this API
    WATER_RANGE_K,
    HydrogelParams,
    gel_psi,
    mixing_g,
    nominal_stresses,
    reference_chemical_potential,
)

J_MAX = 1.0e6  # a gel that would swell beyond this has no equilibrium (mu > 0)
_GRID = np.exp(np.linspace(np.log(1e-9), np.log(J_MAX), 4001))  # values of J - 1


@dataclass(frozen=True)
class SwellingState:
    """A stress-free (in its free directions) equilibrium of the gel at (mu, T).

    Parameters
    ----------
    T : float
        Temperature [K].
    mu : float
        Chemical potential of the solvent [k_B T].
    stretch : float
        Free stretch from the dry network [-].
    stretch_rel : float
        Free stretch from the as-prepared state [-].
    J : float
        Volume ratio to the dry network [-].
    branch : {"swollen", "collapsed"}
        The branch of the equilibrium.
    energy : float
        w per dry volume at equilibrium [k_B T / nu].
    bistable : bool
        Both branches are local minima at this (mu, T).
    """

    T: float
    mu: float
    stretch: float  # free stretch, from the dry network [-]
    stretch_rel: float  # free stretch, from the as-prepared state [-]
    J: float  # volume ratio to the dry network [-]
    branch: str  # "swollen" or "collapsed"
    energy: float  # w per dry volume at equilibrium [k_B T / nu]
    bistable: bool  # both branches are local minima at this (mu, T)


@dataclass(frozen=True)
class Transition:
    """Volume phase transition at fixed mu: T where the two branches have equal energy.

    Parameters
    ----------
    T : float
        Transition temperature [K].
    discontinuous : bool
        Two coexisting minima (a volume jump) rather than a smooth crossover.
    J_swollen, J_collapsed : float
        Volume ratios to the dry network of the two branches at ``T`` [-].
    """

    T: float  # transition temperature [K]
    discontinuous: bool  # two coexisting minima (a volume jump) rather than a smooth crossover
    J_swollen: float
    J_collapsed: float


def _energy(params, mu, T, lam):
    lam = np.asarray(lam, dtype=float)
    I1 = np.sum(lam**2, axis=-1)
    J = np.prod(lam, axis=-1)
    return gel_psi(params, mu, T, I1, J, 0)[0]


def _principal(held: tuple[float, ...], t) -> np.ndarray:
    """Principal stretches (len(t), 3): the held ones, then t in each of the 3 - len(held) free directions."""
    t = np.atleast_1d(t)
    k = 3 - len(held)
    return np.concatenate([np.broadcast_to(held, (t.size, len(held))), np.repeat(t[:, None], k, 1)], 1)


def equilibrium_stretches(params: HydrogelParams, mu: float, T: float, held=()) -> np.ndarray:
    """Every stable stationary free stretch of the gel at (mu, T), ascending.

    ``held`` are principal stretches held fixed (dry reference); the 3 - len(held) others are free
    and equal, t: ``()`` free swelling, ``(lambda0,)`` plane strain (out-of-plane stretch held at
    the as-prepared lambda0), ``(l1, l2)`` a layer bonded to a rigid substrate. A returned t makes
    the free directions' nominal stress zero where it rises through zero, i.e. t is a local
    minimum of the energy over the free stretch (two of them in the bistable window of the volume
    phase transition). Each sign change on a fine logarithmic grid of J - 1 (1e-9 to ``J_MAX``)
    is refined by Brent's method to 1e-14.

    Parameters
    ----------
    params : HydrogelParams
        The gel.
    mu : float
        Chemical potential of the solvent [k_B T].
    T : float
        Temperature [K].
    held : tuple of float, optional
        Principal stretches held fixed, from the dry network [-] (none, one or two).

    Returns
    -------
    ndarray, shape (m,)
        The free stretches t, from the dry network [-].

    Raises
    ------
    ValueError
        Where the gel swells without bound (mu > 0 for a free gel).
    """
    held = tuple(held)
    k = 3 - len(held)
    if k == 3 and mu > 0:  # w ~ 3n/2 l^2 - mu l^3 -> -inf: a free gel swells without bound
        raise ValueError(f"no equilibrium: a free gel swells without bound at mu={mu} kT > 0 (mu must be <= 0)")
    Ph = float(np.prod(held)) if held else 1.0

    def s_free(t):
        return nominal_stresses(params, _principal(held, t), mu, T)[:, -1]

    t = ((1.0 + _GRID) / Ph) ** (1.0 / k)
    s = s_free(t)
    if s[-1] < 0:
        raise ValueError(
            f"no equilibrium: the gel swells without bound at mu={mu} kT, T={T} K (mu must be <= 0)"
        )
    return np.array([brentq(lambda x: s_free(x)[0], t[i], t[i + 1], xtol=1e-14, rtol=1e-14)
                     for i in np.nonzero((s[:-1] < 0) & (s[1:] >= 0))[0]])


def _minima(params: HydrogelParams, mu: float, T: float, held: tuple[float, ...]):
    """All local minima (t, J, w) of w over the free stretch t, equal in the 3 - len(held) free directions."""
    k = 3 - len(held)
    Ph = float(np.prod(held)) if held else 1.0
    return [(tm, Ph * tm**k, float(_energy(params, mu, T, _principal(held, tm))[0]))
            for tm in map(float, equilibrium_stretches(params, mu, T, held))]


def _equilibrium(params, mu, T, held, T_c):
    mins = _minima(params, mu, T, tuple(held))
    t, J, w = min(mins, key=lambda m: m[2])
    if len(mins) > 1:
        branch = "swollen" if J == max(m[1] for m in mins) else "collapsed"
    else:
        branch = "swollen" if T < T_c else "collapsed"
    return SwellingState(T, mu, t, t / params.lambda0, J, branch, w, len(mins) > 1)


def transition_temperature(params: HydrogelParams, mu: float = 0.0, T_range=WATER_RANGE_K) -> Transition:
    """Volume phase transition temperature [K] of the free gel at chemical potential mu [k_B T].

    Where two minima coexist the transition is the Maxwell temperature (equal energies); where the
    swelling curve is continuous, the temperature of the steepest fall of J.

    Parameters
    ----------
    params : HydrogelParams
        The gel.
    mu : float
        Chemical potential of the solvent [k_B T]; 0 is pure water.
    T_range : tuple of float
        The temperatures searched [K] (default: liquid water's range).

    Returns
    -------
    Transition
        The transition temperature ``T`` [K], whether it is ``discontinuous``, and the volume
        ratios (to the dry network) of the two branches there.

    Examples
    --------
    >>> from hydrojam import HydrogelParams, transition_temperature
    >>> tr = transition_temperature(HydrogelParams(), mu=0.0)
    >>> round(tr.T, 1), tr.discontinuous
    (305.4, True)
    """
    Ts = np.linspace(*T_range, 201)
    mins = [_minima(params, mu, T, ()) for T in Ts]
    bist = [i for i, m in enumerate(mins) if len(m) > 1]

    def gap(T):
        m = _minima(params, mu, T, ())
        if len(m) < 2:  # outside the bistable window: the only branch (swollen below it) wins
            return -1.0 if T < Ts[bist[0]] else 1.0
        sw = max(m, key=lambda x: x[1])
        co = min(m, key=lambda x: x[1])
        return sw[2] - co[2]

    if bist:
        lo, hi = Ts[max(bist[0] - 1, 0)], Ts[min(bist[-1] + 1, len(Ts) - 1)]
        Tc = brentq(gap, lo, hi, xtol=1e-9)
        m = _minima(params, mu, Tc, ())
        return Transition(Tc, True, max(x[1] for x in m), min(x[1] for x in m))
    lnJ = np.log([min(m, key=lambda x: x[2])[1] for m in mins])
    i = int(np.argmin(np.gradient(lnJ, Ts)))
    J = np.exp(lnJ[i])
    return Transition(float(Ts[i]), False, J, J)


def free_swelling(params: HydrogelParams, mu: float, T: float, T_c: float | None = None) -> SwellingState:
    """Stable stress-free state of a free gel (F = lambda I) at (mu [k_B T], T [K]).

    Parameters
    ----------
    params : HydrogelParams
        The gel.
    mu : float
        Chemical potential of the solvent [k_B T]; 0 is pure water.
    T : float
        Temperature [K].
    T_c : float, optional
        The transition temperature at ``mu`` [K], if known (it picks the stable branch near the
        transition); computed when not given.

    Returns
    -------
    SwellingState
        The free stretch from the dry network (``stretch``) and from the as-prepared state
        (``stretch_rel``), the volume ratio ``J``, the branch and its energy.

    Raises
    ------
    ValueError
        If ``mu > 0``: a free gel then swells without bound.

    Examples
    --------
    In pure water at 275 K the free gel swells 2.16x beyond its as-prepared size:

    >>> from hydrojam import HydrogelParams, free_swelling
    >>> st = free_swelling(HydrogelParams(), mu=0.0, T=275.0)
    >>> round(st.stretch, 2), round(st.stretch_rel, 2), st.branch
    (3.24, 2.16, 'swollen')
    """
    if T_c is None:
        T_c = transition_temperature(params, mu).T
    return _equilibrium(params, mu, T, (), T_c)


def swelling_curve(params: HydrogelParams, mu: float, temperatures) -> tuple[Transition, list[SwellingState]]:
    """Free-swelling states over a list of temperatures at one chemical potential, and the transition.

    Parameters
    ----------
    params : HydrogelParams
        The gel.
    mu : float
        Chemical potential of the solvent [k_B T].
    temperatures : iterable of float
        Temperatures [K].

    Returns
    -------
    transition : Transition
        The volume phase transition at ``mu``.
    states : list of SwellingState
        The stable free-swelling state at each temperature.
    """
    tr = transition_temperature(params, mu)
    return tr, [_equilibrium(params, mu, float(T), (), tr.T) for T in temperatures]


def constrained_swelling(params: HydrogelParams, mu: float, T: float, held) -> SwellingState:
    """Equilibrium with one or two principal stretches held (dry reference), the others free and equal.

    ``held=(l1,)``: uniaxially constrained (stretch l1 held, two lateral directions free);
    ``held=(l1, l2)``: biaxially constrained, e.g. a layer bonded to a rigid substrate with
    ``held=(lambda0, lambda0)`` swells in thickness only. The free stretches carry zero stress.

    Parameters
    ----------
    params : HydrogelParams
        The gel.
    mu : float
        Chemical potential of the solvent [k_B T].
    T : float
        Temperature [K].
    held : float or tuple of float
        One or two principal stretches held, from the dry network [-].

    Returns
    -------
    SwellingState
        ``stretch`` is the free stretch (from the dry network).

    Raises
    ------
    ValueError
        If ``held`` is not one or two positive stretches, or the gel swells without bound.

    Examples
    --------
    A layer bonded to a rigid substrate, in pure water at 275 K, thickens 3.45x from its
    as-prepared thickness (Hong, Liu & Suo 2009):

    >>> from hydrojam import HydrogelParams, constrained_swelling
    >>> p = HydrogelParams()
    >>> st = constrained_swelling(p, 0.0, 275.0, held=(p.lambda0, p.lambda0))
    >>> round(st.stretch / p.lambda0, 2)
    3.45
    """
    held = tuple(float(h) for h in np.atleast_1d(held))
    if not 1 <= len(held) <= 2 or min(held) <= 0:
        raise ValueError("held must be one or two positive stretches")
    T_c = transition_temperature(params, mu).T if mu <= 0 else np.inf  # no free-gel transition above 0
    return _equilibrium(params, mu, T, held, T_c)


# ------------------------------------------------------------------------------------------------
# Unconfined swelling: plane strain (dimension 2: a cylinder's out-of-plane stretch held at
# lambda0) or free (dimension 3)


def free_stretches(params: HydrogelParams, mus, Ts, dimension: int) -> np.ndarray:
    """Unconfined stretch from the dry network along a sequence of stimuli, followed by
    continuation (the stable equilibrium nearest to the previous one, from lambda0): the branch a
    particle follows. Where a stimulus has no equilibrium (unbounded swelling) the stretch stays
    where it was.

    Parameters
    ----------
    params : HydrogelParams
        The gel.
    mus : sequence of float
        Chemical potentials of the solvent [k_B T].
    Ts : sequence of float
        Temperatures [K], one per chemical potential.
    dimension : {2, 3}
        Plane strain (the out-of-plane stretch held at lambda0) or free swelling.

    Returns
    -------
    ndarray
        The stretch at each stimulus [-].
    """
    held = (params.lambda0,) if dimension == 2 else ()
    out, prev = [], params.lambda0
    for mu, T in zip(mus, Ts):
        try:
            roots = equilibrium_stretches(params, mu, T, held)
        except ValueError:  # no equilibrium (unbounded swelling): the coordinate stays where it was
            roots = np.empty(0)
        if len(roots):
            prev = float(roots[np.argmin(np.abs(np.log(roots / prev)))])
        out.append(prev)
    return np.asarray(out)


def free_log_volume(params: HydrogelParams, lam: np.ndarray, dimension: int) -> np.ndarray:
    """ln J [-] (J the volume ratio to the dry network) of unconfined stretches ``lam`` from the
    dry network [-]: 3 ln lam free (dimension 3), 2 ln lam + ln lambda0 in plane strain (2)."""
    return 3.0 * np.log(lam) if dimension == 3 else 2.0 * np.log(lam) + np.log(params.lambda0)


def effective_chemical_potential(params: HydrogelParams, J, T, dimension: int = 2) -> np.ndarray:
    """The chemical potential mu_eff [k_B T] at which the gel's unconfined equilibrium at
    temperature T [K] holds exactly the volume ratio J (to the dry network): the free principal
    stress n (l - 1/l) + (J/l) g(J; mu, T) vanishes (``nominal_stresses``), and
    g(J; mu, T) = g(J; 0, T) - mu, so

        3D (free, J = l^3):                  mu_eff = g(J; 0, T) + n (l - 1/l) / l^2
        2D (plane strain, J = l^2 lambda0):  mu_eff = g(J; 0, T) + n (l - 1/l) / (l lambda0)

    Parameters
    ----------
    params : HydrogelParams
        The gel.
    J : float or array_like
        Volume ratio to the dry network [-].
    T : float or array_like
        Temperature [K] (broadcast against J).
    dimension : {2, 3}, optional
        Plane strain or free swelling.

    Returns
    -------
    ndarray
        mu_eff [k_B T], of the broadcast shape of J and T.
    """
    J, T = np.broadcast_arrays(np.asarray(J, dtype=float), np.asarray(T, dtype=float))
    if dimension == 3:
        lam = np.cbrt(J)
        per = lam**2
    else:
        lam = np.sqrt(J / params.lambda0)
        per = lam * params.lambda0
    return mixing_g(params, J, 0.0, T) + params.n * (lam - 1.0 / lam) / per


def osmotic_modulus(params: HydrogelParams, J: float, T: float, dimension: int = 2) -> float:
    """The free gel's osmotic modulus K = (kT/nu) d mu_eff / d ln J [MPa] at volume ratio J (to the
    dry network) and temperature T [K] (:func:`effective_chemical_potential`; plane strain in 2D):
    the change of the bath's chemical potential, as a pressure, that changes the free gel's ln J
    by one. Central difference in ln J (relative step 1e-5: error ~1e-10 of K).

    Parameters
    ----------
    params : HydrogelParams
        The gel.
    J : float
        Volume ratio to the dry network [-].
    T : float
        Temperature [K].
    dimension : {2, 3}, optional
        Plane strain or free swelling.

    Returns
    -------
    float
        K [MPa] (negative where the free gel is unstable).
    """
    h = 1e-5
    up, down = effective_chemical_potential(params, J * np.exp(h), T, dimension), \
        effective_chemical_potential(params, J * np.exp(-h), T, dimension)
    return float(params.kT_over_nu * (up - down) / (2 * h))
