"""Gram matrices and predictive variances of a reduced-rank GP's features without their O(n M^2) products.

A Hilbert-space GP term's feature j is prod_d sin(J_jd u_d) / sqrt(prod_d L_d) with u_d = (x_d + L_d) pi / 2 L_d,
and sin(a u) sin(b u) = (cos((a - b) u) - cos((a + b) u)) / 2. So every product of two features is a sum of
2^D products of cosines of integer multiples of u_d, and

- the Gram matrix over any rows is a gather from the table T[p, q] = sum_i cos(p u_1i) cos(q u_2i): O(n P Q)
  with P, Q about twice the largest frequency index per axis (a few thousand entries, not M^2 = 4 million);
- a quadratic form phi_i' C phi_i (the predictive variance) is sum_pq D[p, q] cos(p u_1i) cos(q u_2i), with D
  the scatter of C onto the same table: O(M^2) once, then O(P Q) per point, not O(M^2);
- a linear form phi_i' w (the predictive mean, a slow term's covariance with the block) is sum_pq A[p, q]
  sin(p u_1i) sin(q u_2i) with A the weights laid on a (max J_1, max J_2) table: prediction never forms the
  n x M features, whose sine products cost more than the table's one matrix product.

For terms on one or two inputs; the results equal the direct products to rounding (tests compare them).
"""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np
from forcemap.host.workbench.engine import nufft
from scipy import linalg

# a GP term gets the fast path from this many basis functions on (below it the direct products are cheap)
MIN_FAST_BASIS = 64


def is_fast(term) -> bool:
    return (
        hasattr(term, "angles")
        and 1 <= getattr(term, "dims", 0) <= 2
        and len(getattr(term, "J", ())) >= MIN_FAST_BASIS
        and term.J.shape[1] <= 2
    )


def _phases(u: np.ndarray, top: int) -> np.ndarray:
    """exp(i p u) for p = 0 .. top: (n, top + 1). Two tables of about sqrt(top) exponentials multiplied out,
    exp(i (q b + r) u) = exp(i q b u) exp(i r u), not top sines and cosines: within a few ulps of them."""
    b = max(1, math.isqrt(top + 1))
    low = np.exp(1j * (u[:, None] * np.arange(b)[None, :]))
    high = np.exp(1j * (u[:, None] * (b * np.arange(top // b + 1))[None, :]))
    return (high[:, :, None] * low[:, None, :]).reshape(len(u), -1)[:, : top + 1]


class Points:
    """What `waves` gives with finufft: the points' angles, at which `linear_form` and `quadratic_form` evaluate
    their tables by type-2 non-uniform FFTs (O(n w^D) a column) instead of the n x P_d sines and cosines."""

    def __init__(self, angles: list[np.ndarray]) -> None:
        self.angles = angles


def waves(term, Z: np.ndarray, cosines: bool = True):
    """Per input axis, cos(p u_d) for p = 0 .. 2 max J_d (with `cosines`) and sin(p u_d) / sqrt(L_d) for
    p = 1 .. max J_d, (n, P_d) each: the tables of `quadratic_form` and of `linear_form`, from one set of phases.
    With finufft, `Points` instead (the forms are then non-uniform FFTs)."""
    if nufft.available():
        return Points(term.angles(Z))
    cos, sin = [], []
    for d, u in enumerate(term.angles(Z)):
        top = int(term.J[:, d].max())
        ph = _phases(u, 2 * top if cosines else top)
        if cosines:
            cos.append(np.ascontiguousarray(ph.real))
        sin.append(ph.imag[:, 1 : top + 1] / math.sqrt(term.L[d]))
    return cos, sin


def _cosines(term, Z: np.ndarray) -> list[np.ndarray]:
    """cos(p u_d) for p = 0 .. 2 max J_d, per input axis: (n, P_d) each."""
    out = []
    for d, u in enumerate(term.angles(Z)):
        out.append(np.ascontiguousarray(_phases(u, 2 * int(term.J[:, d].max())).real))
    return out


def _combos(term) -> list[tuple[float, np.ndarray]]:
    """(sign, flat table index (M, M)) of every cosine product in phi_j phi_k."""
    J = np.ascontiguousarray(term.J, dtype=np.int32)
    return _combos_of(J.tobytes(), J.shape)


def _lower_combos(term) -> tuple[tuple[np.ndarray, np.ndarray], list[tuple[float, np.ndarray]]]:
    """The lower triangle's (row, column) indices (row-major) and `_combos`' flat table indices there."""
    J = np.ascontiguousarray(term.J, dtype=np.int32)
    return _lower_combos_of(J.tobytes(), J.shape)


@functools.lru_cache(maxsize=2)
def _lower_combos_of(J_bytes: bytes, shape: tuple[int, int]):
    J = np.frombuffer(J_bytes, np.int32).reshape(shape)
    low = np.tril_indices(shape[0])
    sizes = [2 * int(J[:, d].max()) + 1 for d in range(shape[1])]
    out = []
    for combo in itertools.product((0, 1), repeat=shape[1]):
        flat = np.zeros(len(low[0]), np.int32)
        for d, plus in enumerate(combo):
            a, b = J[low[0], d], J[low[1], d]
            flat = flat * sizes[d] + (a + b if plus else np.abs(a - b))
        out.append((-1.0 if sum(combo) % 2 else 1.0, flat))
    return low, out


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
    """The term's Gram matrix Phi'Phi over the rows of `Z`: its cosine table by a non-uniform FFT of ones
    (`nufft`, O(n w^D + K log K)) when finufft is at hand, else summed directly (O(n K_1 K_2))."""
    if nufft.available():
        tops = [2 * int(term.J[:, d].max()) for d in range(term.J.shape[1])]
        F = nufft.exponential_sums(term.angles(Z), np.ones((len(Z), 1)), tops)
        return gram_of_table(term, _cosine_table(F[0], tops))
    cos = _cosines(term, Z)
    T = cos[0].T @ cos[1] if len(cos) == 2 else cos[0].sum(axis=0)
    return gram_of_table(term, T)


def _cosine_table(F: np.ndarray, tops: list[int]) -> np.ndarray:
    """T[p, q] = sum_i w_i cos(p u_i) cos(q v_i), p, q >= 0, from the exponential sums of the weights."""
    K1 = tops[0]
    if len(tops) == 1:
        return F[K1:].real
    K2 = tops[1]
    return 0.5 * (F[K1:, K2:] + F[K1:, K2::-1]).real


def _sine_products(term, F: np.ndarray, tops: list[int]) -> np.ndarray:
    """Phi'w for the weight columns whose exponential sums are F (k, ...): sum_i w_i sin(a u_i) sin(b v_i) is
    Im F[a] in one dimension and (Re F[a, -b] - Re F[a, b]) / 2 in two, gathered at the features' (a, b)."""
    J = term.J
    a = tops[0] + J[:, 0]
    if len(tops) == 1:
        out = F[:, a].imag
    else:
        b = J[:, 1]
        out = 0.5 * (F[:, a, tops[1] - b] - F[:, a, tops[1] + b]).real
    return out.T / math.sqrt(float(np.prod(term.L)))


def gram_of_table(term, T: np.ndarray) -> np.ndarray:
    """The Gram matrix from its cosine table (the sums over some rows): the signed gather of every product,
    over the lower triangle (the matrix is symmetric: its table indices are) and mirrored."""
    T = np.ascontiguousarray(T).ravel()
    low, combos = _lower_combos(term)
    acc = np.zeros(len(low[0]))
    for sign, flat in combos:
        if sign > 0:
            acc += T[flat]
        else:
            acc -= T[flat]
    acc *= _scale(term)
    G = np.empty((len(term.J), len(term.J)))
    G[low] = acc
    G.T[low] = acc
    return G


def transpose_products(term, Z: np.ndarray, W: np.ndarray, rows: int = 4096) -> np.ndarray:
    """Phi' W for the term's features Phi at the rows of `Z` and a few columns W (n x k): (M, k).

    Column c is the gather of the table sum_i w_ic sin(p u_1i) sin(q u_2i) at (J_j1, J_j2): one n x K_1 x K_2
    matrix product (K_d about the largest frequency index, a few thousand products per row in all) instead of
    the n x M features and their product. Worth it for a few columns (a Gram matrix's cross products with a
    constant, Phi'r); for many, the features are cheaper. With finufft, the tables are non-uniform FFTs of the
    columns (`nufft`): O(n w^D) per column, cheaper than the features for any number of them."""
    W = np.asarray(W, float).reshape(len(Z), -1)
    J = term.J - 1
    if W.shape[1] == 0:  # a model of this one term: nothing to cross it with
        return np.zeros((len(J), 0))
    if nufft.available():
        tops = [int(term.J[:, d].max()) for d in range(term.J.shape[1])]
        return _sine_products(term, nufft.exponential_sums(term.angles(Z), W, tops), tops)
    tables = None
    for a in range(0, len(Z), rows):
        S = waves(term, Z[a : a + rows], cosines=False)[1]
        w = W[a : a + rows]
        if len(S) == 1:
            part = [S[0].T @ w]
        else:
            part = [(S[0] * w[:, c : c + 1]).T @ S[1] for c in range(w.shape[1])]
        tables = part if tables is None else [t + p for t, p in zip(tables, part, strict=True)]
    if tables is None:
        return np.zeros((len(J), W.shape[1]))
    if J.shape[1] == 1:
        return tables[0][J[:, 0]]
    return np.column_stack([t[J[:, 0], J[:, 1]] for t in tables])


def variance_table(term, C: np.ndarray, lower: bool = False) -> np.ndarray:
    """The table D with phi' C phi = sum_pq D[p, q] cos(p u_1) cos(q u_2); C may also be a symmetric matrix's
    lower triangle with its off-diagonal entries doubled (phi_j phi_k and phi_k phi_j share a table entry),
    then only that triangle is read (``lower``)."""
    sizes = [2 * int(term.J[:, d].max()) + 1 for d in range(term.J.shape[1])]
    size = math.prod(sizes)
    D = np.zeros(size)
    if lower:
        low, combos = _lower_combos(term)
        w = np.asarray(C)[low]
    else:
        combos, w = _combos(term), np.ascontiguousarray(C).ravel()
    for sign, flat in combos:
        D += sign * np.bincount(flat.ravel(), weights=w, minlength=size)
    return (D * _scale(term)).reshape(sizes)


def quadratic_form(term, Z: np.ndarray, D: np.ndarray, tables: tuple | None = None) -> np.ndarray:
    """phi_i' C phi_i at the rows of `Z`, from `variance_table(term, C)` (and `waves(term, Z)` if at hand)."""
    if tables is None and nufft.available():
        tables = Points(term.angles(Z))
    if isinstance(tables, Points):
        return _quadratic_by_nufft(D, tables.angles)
    cos = _cosines(term, Z) if tables is None else tables[0]
    if len(cos) == 1:
        return cos[0] @ D
    return np.einsum("ip,ip->i", cos[0] @ D, cos[1])


def linear_table(term, W: np.ndarray) -> np.ndarray:
    """Tables A (k, P_1[, P_2]) with phi' W[:, c] = sum_pq A[c, p, q] s_1p s_2q, s_d the sines of `waves`: each
    feature is one product of one sine per axis, so the M weights of a column of `W` (M, k) scatter onto distinct
    entries."""
    W = np.asarray(W, float).reshape(len(term.J), -1)
    sizes = [int(term.J[:, d].max()) for d in range(term.J.shape[1])]
    flat = np.zeros(len(term.J), np.int64)
    for d, size in enumerate(sizes):
        flat = flat * size + (term.J[:, d] - 1)
    A = np.zeros((W.shape[1], math.prod(sizes)))
    A[:, flat] = W.T
    return A.reshape(W.shape[1], *sizes)


def linear_form(term, Z: np.ndarray, A: np.ndarray, tables: tuple | None = None) -> np.ndarray:
    """Phi W (n, k) at the rows of `Z` from `linear_table(term, W)` (and `waves(term, Z)` if at hand), without
    forming the n x M features: O(n P_1 P_2 k) in one matrix product, with P_1 P_2 about M."""
    tables = waves(term, Z, cosines=False) if tables is None else tables
    if isinstance(tables, Points):
        return _linear_by_nufft(term, A, tables.angles)
    s = tables[1]
    if len(s) == 1:
        return s[0] @ A.T
    k, p1, p2 = A.shape
    left = s[0] @ A.transpose(1, 0, 2).reshape(p1, k * p2)
    return np.einsum("ikq,iq->ik", left.reshape(len(Z), k, p2), s[1])


def _quadratic_by_nufft(D: np.ndarray, angles: list[np.ndarray]) -> np.ndarray:
    """sum_pq D[p, q] cos(p u) cos(q v) at the points: cos(p u) cos(q v) is the mean of the four exp(i (+-p u
    +- q v)), so the table mirrored into every quadrant (p = 0 counted twice, as cos(0) = (1 + 1) / 2) over 4."""
    tops = [s - 1 for s in D.shape]
    full = np.zeros([2 * t + 1 for t in tops])
    quadrant = tuple(slice(t, None) for t in tops)
    full[quadrant] = D
    out = full.copy()
    for axes in ([0], [1], [0, 1])[: 2 ** len(tops) - 1]:
        out += np.flip(full, axis=axes)
    return nufft.exponential_values(angles, out / 2 ** len(tops), tops)[:, 0].real


def _linear_by_nufft(term, A: np.ndarray, angles: list[np.ndarray]) -> np.ndarray:
    """Phi W (n, k) from `linear_table`'s A (k, P_1[, P_2]): sin(a u) = (exp(i a u) - exp(-i a u)) / 2i, so A
    laid at +-a (+-b) with the signs and the 1 / (2i)^D of that product, one type-2 FFT per column."""
    k, sizes = A.shape[0], A.shape[1:]
    full = np.zeros((k, *[2 * p + 1 for p in sizes]), complex)
    D = len(sizes)
    for signs in itertools.product((1, -1), repeat=D):
        idx = tuple(
            slice(p + 1, None) if s > 0 else slice(p - 1, None, -1)
            for p, s in zip(sizes, signs, strict=True)
        )
        full[(slice(None), *idx)] += math.prod(signs) * A
    full /= (2j) ** D * math.sqrt(float(np.prod(term.L)))
    return nufft.exponential_values(angles, full, list(sizes)).real


def posterior_tables(term, cols: tuple[slice, np.ndarray], post: dict) -> None:
    """Put in a posterior `post` (mu, L, s: Sigma = diag(s) (L L')^-1 diag(s)), once, what its variances need: the
    fast block's (columns `cols[0]`, GP `term`) cosine `table` of Sigma, Sigma's rows of the other blocks'
    columns `cols[1]` (`cov_slow`), and their covariances with the block as a sine table (`cross_table`)."""
    if "table" in post:
        return
    fcols, slow = cols
    inv, info = linalg.lapack.dpotri(post["L"], lower=1)  # B^-1, B = L L', in the lower triangle
    if info != 0:
        raise np.linalg.LinAlgError("dpotri failed")
    inv *= post["s"][:, None]
    inv *= post["s"][None, :]
    low = np.tril(inv)
    ff = low[fcols, fcols]
    weights = 2.0 * ff - np.diag(np.diag(ff))  # the lower triangle counts for the upper one too
    rows = low[slow] + low[:, slow].T
    rows[np.arange(len(slow)), slow] -= np.diag(low)[slow]
    post["cov_slow"] = rows
    if len(slow):
        post["cross_table"] = linear_table(term, rows[:, fcols].T)
    post["table"] = variance_table(term, weights, lower=True)


def variance(
    term, Z, cols, post: dict, S: np.ndarray, cross, tables: tuple | None = None
) -> np.ndarray:
    """phi' Sigma phi at the rows of `Z` (the fast block's inputs), with `posterior_tables`: the block's part from
    the cosine table, not an M x M product per row; `S` the other blocks' features there, `cross` the block's
    features times Sigma[other columns, block]'; `tables` from `waves(term, Z)` if at hand."""
    var = quadratic_form(term, Z, post["table"], tables)
    if S.shape[1]:
        var += 2.0 * np.einsum("ij,ij->i", S, cross)
        var += np.einsum("ij,ij->i", S @ post["cov_slow"][:, cols[1]], S)
    return var
