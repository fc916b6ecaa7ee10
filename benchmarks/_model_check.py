"""How far Newton's quadratic model holds along its own steps, term by term
(``benchmarks/path.py --model-check N``): an observer of the solver's line searches
(:class:`hydrojam.fem.solver.events.LineSearch`) that, at every N-th backtracking search,
evaluates each energy term along the direction d from the iterate at a = 1/4, 1/2 and 1 of the
step cap (the contact's CCD cap; 1 where nothing caps it):

- ``deviation`` [mJ]: E_t(x + a d) - E_t(x) - (a g_t.d + a^2/2 d.H_t.d), with the term's exact
  gradient and Hessian at x, reported relative to the whole model's decrease |sum over the terms
  of a g_t.d + a^2/2 d.H_t.d|;
- for the contact term, that deviation split into the barrier of the pairs ipctk found at x
  (``barrier, pairs at x``: those pairs' barrier evaluated at x + a d, against their own model),
  the barrier of pairs that are new at x + a d (``barrier, new pairs``) and the lagged friction
  (``friction``, the rest);
- for every pair found at x, its own barrier's deviation from its own quadratic model at the
  capped step, and its gap before and after that step.

The summary gives the medians and 90 % quantiles, and, among the iterations whose whole deviation
at the capped step exceeds a quarter of the model's decrease (the model no longer describes the
step), which piece was the largest, how many pairs (the largest deviations first) account for
the excess, and whether the largest one closes, opens or leaves the barrier's range. The extra
evaluations (one Hessian per term, three energies, each pair's barrier at both ends) make a
checked iteration about twice as expensive; the path itself is untouched.
"""

from __future__ import annotations

import collections

import numpy as np
import scipy.sparse as sp

from hydrojam.fem import Observer

FRACTIONS = (0.25, 0.5, 1.0)
CONTACT_PIECES = ("barrier, pairs at x", "barrier, new pairs", "friction")


def _inner(term):
    return getattr(term, "_term", term)  # inside a TimedTerm (simulate's clocks)


def _is_ipc_contact(term) -> bool:
    inner = _inner(term)
    return all(hasattr(inner, a) for a in ("_collisions", "_barrier", "_cm", "_vertices"))


def term_deviations(terms, x: np.ndarray, step: np.ndarray, shape, cap: float,
                    fractions=FRACTIONS) -> tuple[dict, dict, np.ndarray]:
    """Each term's deviation from its quadratic model along ``step`` at ``fractions`` of ``cap``.

    Parameters
    ----------
    terms : sequence of EnergyTerm
    x, step : ndarray
        The flat state [mm] and Newton direction [mm] (all DOFs, zero on the fixed ones).
    shape : tuple
        The nodal shape (n, d) of x.
    cap : float
        The step cap (fraction of ``step``) the line search starts from.

    Returns
    -------
    deviations : dict
        ``(name, a) -> deviation [mJ]`` for every term, and for an IPC contact term its pieces
        (:data:`CONTACT_PIECES`).
    models : dict
        ``a -> the whole quadratic model's change [mJ]`` at a x cap.
    pairs : ndarray, shape (n, 3)
        For every contact pair at x: its barrier's deviation from its own quadratic model at the
        capped step [mJ], and its gap at x and at x + cap step, both over dhat.
    """
    X = x.reshape(shape)
    dev, models = {}, collections.Counter()
    pairs = []
    for t in terms:
        e0 = t.energy(X)
        gd = float(t.gradient(X).ravel() @ step)
        dHd = float(step @ (t.hessian(X) @ step))
        for a in fractions:
            h = a * cap
            model = h * gd + 0.5 * h * h * dHd
            dev[(t.name, a)] = t.energy((x + h * step).reshape(shape)) - e0 - model
            models[a] += model
        if not _is_ipc_contact(t):
            continue
        c = _inner(t)
        V0, col0 = c._collisions(X)
        b0 = float(c._barrier(col0, c._cm, V0))
        gb = c._cm.to_full_dof(c._barrier.gradient(col0, c._cm, V0))
        Hb = sp.csr_matrix(c._cm.to_full_dof(sp.csc_matrix(c._barrier.hessian(col0, c._cm, V0))))
        bgd, bdHd = float(gb @ step), float(step @ (Hb @ step))
        for a in fractions:
            h = a * cap
            Va = c._vertices((x + h * step).reshape(shape))
            fixed = float(c._barrier(col0, c._cm, Va))
            _, cola = c._collisions((x + h * step).reshape(shape))
            full = float(c._barrier(cola, c._cm, Va))
            model = h * bgd + 0.5 * h * h * bdHd
            dev[(CONTACT_PIECES[0], a)] = fixed - b0 - model
            dev[(CONTACT_PIECES[1], a)] = full - fixed
            dev[(CONTACT_PIECES[2], a)] = dev[(t.name, a)] - (full - b0 - model)
        D = c._vertices((x + cap * step).reshape(shape)) - V0
        E, F, b, dhat = c._cm.edges, c._cm.faces, c._barrier, c.settings.dhat
        for group in (col0.vv_collisions, col0.ev_collisions, col0.fv_collisions, col0.ee_collisions):
            for k in group:
                xk, dk = k.dof(V0, E, F), k.dof(D, E, F)
                model = float(b.gradient(k, xk) @ dk + 0.5 * dk @ (b.hessian(k, xk) @ dk))
                pairs.append((b(k, xk + dk) - b(k, xk) - model, np.sqrt(k.compute_distance(xk)) / dhat,
                              np.sqrt(max(k.compute_distance(xk + dk), 0.0)) / dhat))
    return dev, dict(models), np.array(pairs, dtype=float).reshape(-1, 3)


#: the most pairs :func:`pairs_accounting` counts before it says "more"
MOST_PAIRS = 3


def pairs_accounting(total: float, pair_deviations: np.ndarray, bound: float) -> int | None:
    """How many pairs, the largest deviations first, must be taken out of a step's whole deviation
    ``total`` [mJ] to bring it within ``bound`` [mJ]: 0 to :data:`MOST_PAIRS`, None beyond."""
    order = np.argsort(-np.abs(pair_deviations), kind="stable")
    rest = total - np.concatenate([[0.0], np.cumsum(pair_deviations[order])])
    within = np.flatnonzero(np.abs(rest[:MOST_PAIRS + 1]) <= bound)
    return int(within[0]) if within.size else None


def pair_move(d0: float, d1: float) -> str:
    """What a pair's gap does over a step, both gaps over dhat: it leaves the barrier's range
    (d1 >= 1), closes, or opens within it."""
    return "leaves dhat" if d1 >= 1.0 else ("closes" if d1 < d0 else "opens within dhat")


class ModelCheck(Observer):
    """Checks the quadratic model at every ``every``-th backtracking line search it observes (the
    terms are evaluated at the search's iterate, which the search leaves as it was)."""

    def __init__(self, every: int = 5):
        if every < 1:
            raise ValueError(f"every must be a positive integer, got {every}")
        self.every = every
        self.samples: list[tuple[dict, dict]] = []
        self.pairs: list[np.ndarray] = []
        self._calls = 0

    def on_line_search(self, event) -> None:
        if not event.searched:  # a full step judged by its residual: no search to check
            return
        self._calls += 1
        if self._calls % self.every == 0:
            x = np.asarray(event.x, dtype=float)
            dev, models, pairs = term_deviations(event.terms, x.ravel(), np.ravel(event.step), x.shape, event.cap)
            self.samples.append((dev, models))
            self.pairs.append(pairs)

    def pieces(self) -> list[str]:
        """The names checked, terms first, then the contact's pieces."""
        names = []
        for dev, _ in self.samples:
            for name, _a in dev:
                if name not in names:
                    names.append(name)
        return names

    def summary(self, label: str) -> str:
        """The deviations relative to the model's decrease, and the dominant piece where it fails."""
        if not self.samples:
            return f"  {label}: no iterations checked"
        names = self.pieces()
        lines = [f"  {label}: the quadratic model along {len(self.samples)} checked Newton steps "
                 f"(one in {self.every}); |deviation| / |model decrease|, median / 90 % quantile"]
        for a in FRACTIONS:
            parts = []
            for n in names:
                v = [abs(dev[(n, a)]) / max(abs(m[a]), 1e-300) for dev, m in self.samples if (n, a) in dev]
                parts.append(f"{n} {np.median(v):.2g} / {np.quantile(v, 0.9):.2g}")
            lines.append(f"    at {a:g} of the capped step: " + "; ".join(parts))
        leaves = [n for n in names if n != "contact"] if any(n in CONTACT_PIECES for n in names) else names
        worst, failed = collections.Counter(), 0
        explained, moves = collections.Counter(), collections.Counter()
        for (dev, m), pairs in zip(self.samples, self.pairs):
            total = sum(dev[(n, 1.0)] for n in leaves if (n, 1.0) in dev)
            bound = 0.25 * abs(m[1.0])
            if abs(total) > bound:
                failed += 1
                worst[max((n for n in leaves if (n, 1.0) in dev), key=lambda n: abs(dev[(n, 1.0)]))] += 1
                if len(pairs):
                    count = pairs_accounting(total, pairs[:, 0], bound)
                    explained[f"{count}" if count is not None else f"more than {MOST_PAIRS}"] += 1
                    moves[pair_move(*pairs[np.argmax(np.abs(pairs[:, 0])), 1:])] += 1
        lines.append(f"    the model off by more than a quarter at the capped step in {failed} of "
                     f"{len(self.samples)}; the largest piece there: "
                     + (", ".join(f"{n} {k}" for n, k in worst.most_common()) or "-"))
        if explained:
            lines.append("    there, the pairs (the largest deviations first) that account for the excess: "
                         + ", ".join(f"{n} in {k}" for n, k in sorted(explained.items()))
                         + "; the largest pair " + ", ".join(f"{n} in {k}" for n, k in moves.most_common()))
        pairs = np.concatenate(self.pairs) if self.pairs else np.zeros((0, 3))
        if len(pairs):
            gaps = (pairs[:, 2] - pairs[:, 1]) / pairs[:, 1]
            lines.append(f"    contact pairs' gap change over the capped step, |(d1 - d0) / d0|: median "
                         f"{np.median(np.abs(gaps)):.2g}, 90 % {np.quantile(np.abs(gaps), 0.9):.2g}; closing by more "
                         f"than 30 %: {np.mean(gaps < -0.3):.2%} of {gaps.size} pair samples "
                         f"({np.sum(gaps < -0.3) / len(self.samples):.1f} a checked step)")
        return "\n".join(lines)
