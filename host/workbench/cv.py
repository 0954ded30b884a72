"""Cross-validation folds (spatially blocked or random), error metrics and the paired test between two models."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

TARGET_BLOCKS = 25
DEFAULT_FOLDS = 5


def spatial_blocks(xy: np.ndarray, target: int = TARGET_BLOCKS) -> np.ndarray:
    """Square grid cells over the track, sized so that about `target` cells hold samples; the cell id per sample."""
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    span = np.maximum(hi - lo, 1e-6)
    size = float(np.sqrt(span.prod() / target)) or float(span.max() / target)
    ids = np.zeros(len(xy), int)
    for _ in range(30):
        cell = np.floor((xy - lo) / size).astype(int)
        _, ids = np.unique(cell[:, 0] * 1_000_003 + cell[:, 1], return_inverse=True)
        count = ids.max() + 1
        if 0.7 * target <= count <= 1.4 * target:
            break
        size *= np.sqrt(count / target)
    return ids


def blocked_folds(
    xy: np.ndarray, k: int = DEFAULT_FOLDS, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Whole spatial blocks go to one fold, each in a random order to the fold that holds the fewest samples so
    far. Returns (fold, block) per sample.

    Taking the blocks largest first would balance the folds more tightly, but then the order, and so the
    assignment, hardly depends on the seed: repeated assignments would repeat one draw of the lottery."""
    blocks = spatial_blocks(xy)
    nb = blocks.max() + 1
    k = min(k, nb)
    rng = np.random.default_rng(seed)
    sizes = np.bincount(blocks, minlength=nb)
    order = rng.permutation(nb)
    load = np.zeros(k)
    fold_of_block = np.empty(nb, int)
    for b in order:
        f = int(np.argmin(load + rng.uniform(0, 1e-9, k)))
        fold_of_block[b] = f
        load[f] += sizes[b]
    return fold_of_block[blocks], blocks


def repeated_blocked_folds(
    xy: np.ndarray, k: int, seed: int, repeats: int
) -> tuple[list[np.ndarray], np.ndarray]:
    """`repeats` assignments of the same spatial blocks to folds (seeds seed, seed + 1, ...), and the block per
    sample. Which neighbours a block loses with it is a lottery: a corner block held out with the two next to
    it is extrapolated far, and one such block can move a survey's RMSE by 20 %. Averaging the squared
    errors over assignments is repeated k-fold cross-validation."""
    assignments = [blocked_folds(xy, k, seed + r) for r in range(repeats)]
    return [a[0] for a in assignments], assignments[0][1]


def random_folds(n: int, k: int = DEFAULT_FOLDS, seed: int = 0) -> np.ndarray:
    """Each sample to a random fold: neighbours along the track land in different folds."""
    rng = np.random.default_rng(seed)
    return rng.permutation(np.arange(n) % k)


@dataclass
class CVResult:
    """Held-out predictions of the target and the measured values, with errors and 95 % interval coverage."""

    measured: np.ndarray
    predicted: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    circular: bool = False

    @classmethod
    def concat(cls, results: list[CVResult]) -> CVResult:
        """Several cross-validations of the same samples as one: errors and coverage pooled."""
        if len(results) == 1:
            return results[0]
        return cls(
            *(
                np.concatenate([getattr(r, f) for r in results])
                for f in ("measured", "predicted", "lower", "upper")
            ),
            circular=results[0].circular,
        )

    @property
    def error(self) -> np.ndarray:
        e = self.measured - self.predicted
        return (e + 180.0) % 360.0 - 180.0 if self.circular else e

    @property
    def rmse(self) -> float:
        return float(np.sqrt(np.mean(self.error**2)))

    @property
    def mae(self) -> float:
        return float(np.mean(np.abs(self.error)))

    @property
    def coverage95(self) -> float:
        if self.circular:
            half = (self.upper - self.lower) / 2
            return float(np.mean(np.abs(self.error) <= half))
        return float(np.mean((self.measured >= self.lower) & (self.measured <= self.upper)))


def paired_test(
    base_sq: np.ndarray, cand_sq: np.ndarray, groups: np.ndarray
) -> tuple[float, float]:
    """Relative RMSE drop of the candidate, and the one-sided p-value that its squared error is lower.

    The paired unit is the spatial block (blocks are roughly independent; samples along a track are not), and
    the test is Wilcoxon's signed-rank test on the per-block mean squared-error differences: a block at the
    survey's edge where one model extrapolates wildly must not decide the verdict alone."""
    rmse_b, rmse_c = np.sqrt(base_sq.mean()), np.sqrt(cand_sq.mean())
    improvement = float((rmse_b - rmse_c) / rmse_b) if rmse_b > 0 else 0.0
    ng = groups.max() + 1
    counts = np.bincount(groups, minlength=ng)
    keep = counts > 0
    d = np.bincount(groups, weights=base_sq - cand_sq, minlength=ng)[keep] / counts[keep]
    scale = max(float(np.abs(d).max()), 1e-300)
    if len(d) < 6 or np.all(np.abs(d) <= 1e-12 * scale) or scale <= 1e-300:
        return improvement, 1.0
    p = float(stats.wilcoxon(d, alternative="greater").pvalue)
    return improvement, p
