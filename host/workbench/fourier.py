"""Gram matrices and predictive variances of a reduced-rank GP's features without their O(n M^2) products.

A Hilbert-space GP term's feature j is prod_d sin(J_jd u_d) / sqrt(prod_d L_d) with u_d = (x_d + L_d) pi / 2 L_d,
and sin(a u) sin(b u) = (cos((a - b) u) - cos((a + b) u)) / 2. So every product of two features is a sum of
2^D products of cosines of integer multiples of u_d, and

- the Gram matrix over any rows is a gather from the table T[p, q] = sum_i cos(p u_1i) cos(q u_2i): O(n P Q)
  with P, Q about twice the largest frequency index per axis (a few thousand entries, not M^2 = 4 million);
- a quadratic form phi_i' C phi_i (the predictive variance) is sum_pq D[p, q] cos(p u_1i) cos(q u_2i), with D
  the scatter of C onto the same table: O(M^2) once, then O(P Q) per point, not O(M^2).

For terms on one or two inputs; the results equal the direct products to rounding (tests compare them).
"""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np

# a GP term gets the fast path from this many basis functions on (below it the direct products are cheap)
MIN_FAST_BASIS = 64


def is_fast(term) -> bool:
    return (
        hasattr(term, "angles")
        and 1 <= getattr(term, "dims", 0) <= 2
        and len(getattr(term, "J", ())) >= MIN_FAST_BASIS
        and term.J.shape[1] <= 2
    )


def _cosines(term, Z: np.ndarray) -> list[np.ndarray]:
    """cos(p u_d) for p = 0 .. 2 max J_d, per input axis: (n, P_d) each."""
    out = []
    for d, u in enumerate(term.angles(Z)):
        p = np.arange(2 * int(term.J[:, d].max()) + 1)
        out.append(np.cos(u[:, None] * p[None, :]))
    return out


def _combos(term) -> list[tuple[float, np.ndarray]]:
    """(sign, flat table index (M, M)) of every cosine product in phi_j phi_k."""
    J = np.ascontiguousarray(term.J, dtype=np.int32)
    return _combos_of(J.tobytes(), J.shape)


@functools.lru_cache(maxsize=2)
def _combos_of(J_bytes: bytes, shape: tuple[int, int]) -> list[tuple[float, np.ndarray]]:
    J = np.frombuffer(J_bytes, np.int32).reshape(shape)
    dims = J.shape[1]
    sizes = [2 * int(J[:, d].max()) + 1 for d in range(dims)]
    out = []
    for combo in itertools.product((0, 1), repeat=dims):
        flat = np.zeros((len(J), len(J)), np.int32)
        for d, plus in enumerate(combo):
            a = J[:, d]
            idx = a[:, None] + a[None, :] if plus else np.abs(a[:, None] - a[None, :])
            flat = flat * sizes[d] + idx
        out.append((-1.0 if sum(combo) % 2 else 1.0, flat))
    return out


def _scale(term) -> float:
    """kappa / 2^D: the features' normalization and the product-to-sum halves."""
    return 1.0 / float(np.prod(term.L)) / 2 ** term.J.shape[1]


def gram(term, Z: np.ndarray) -> np.ndarray:
    """The term's Gram matrix Phi'Phi over the rows of `Z`."""
    cos = _cosines(term, Z)
    T = cos[0].T @ cos[1] if len(cos) == 2 else cos[0].sum(axis=0)
    T = T.ravel()
    G = np.zeros((len(term.J), len(term.J)))
    for sign, flat in _combos(term):
        G += sign * T[flat]
    return G * _scale(term)


def variance_table(term, C: np.ndarray) -> np.ndarray:
    """The table D with phi' C phi = sum_pq D[p, q] cos(p u_1) cos(q u_2); C may also be a symmetric matrix's
    lower triangle with its off-diagonal entries doubled (phi_j phi_k and phi_k phi_j share a table entry)."""
    sizes = [2 * int(term.J[:, d].max()) + 1 for d in range(term.J.shape[1])]
    size = math.prod(sizes)
    D = np.zeros(size)
    w = np.ascontiguousarray(C).ravel()
    for sign, flat in _combos(term):
        D += sign * np.bincount(flat.ravel(), weights=w, minlength=size)
    return (D * _scale(term)).reshape(sizes)


def quadratic_form(term, Z: np.ndarray, D: np.ndarray) -> np.ndarray:
    """phi_i' C phi_i at the rows of `Z`, from `variance_table(term, C)`."""
    cos = _cosines(term, Z)
    if len(cos) == 1:
        return cos[0] @ D
    return np.einsum("ip,ip->i", cos[0] @ D, cos[1])
