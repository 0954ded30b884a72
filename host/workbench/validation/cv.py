"""Cross-validation folds (spatially blocked or random), error metrics and the paired test between two models."""

from __future__ import annotations

import math
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
        """The share of held-out samples inside the model's own predictive 95 % band."""
        return float(np.mean(self.band_ratio <= 1.0))

    @property
    def band_ratio(self) -> np.ndarray:
        """Each held-out error over the band's half-width on its side: at most 1 inside the band."""
        e = self.error
        if self.circular:
            half = (self.upper - self.lower) / 2
        else:
            half = np.where(e >= 0, self.upper - self.predicted, self.predicted - self.lower)
        half = np.maximum(half, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.abs(e) / half
        return np.where(np.isfinite(r), r, np.where(np.abs(e) > 0, np.inf, 0.0))


# the predictive sd of a map is widened where its band covers less than 95 % of held-out samples, and narrowed
# only where it covers more than OVER_COVERAGE (a factor below 1 from some folds' luck would narrow a band that
# the other folds need wide); by at most this much either way (a wildly wrong model must not be made to look
# calibrated by one factor)
MAX_SD_SCALE = 10.0
OVER_COVERAGE = 0.98
# cells farther from every sample than the distance within which this share of the CV's held-out samples lay
# from their training samples are an extrapolation the CV did not test
REACH_QUANTILE = 0.9


@dataclass
class Calibration:
    """How far the model's predictive band is from its nominal 95 % on held-out data, and the factor that
    brings it there.

    `model_coverage`: the share of blocked-CV held-out samples inside the model's own predictive 95 % band
    (latent plus noise variance). `sd_scale`: the factor on the band's half-widths (the maps' sd) that puts
    95 % of the held-out samples inside it (at least 1 unless the model's own band covers more than
    OVER_COVERAGE). `coverage`: the coverage of the scaled band, cross-fitted: each
    fold's samples are judged by the factor the other folds' samples give (so it is not 95 % by
    construction). `reach_m`: how far from their training samples the CV's held-out samples lay (the
    REACH_QUANTILE quantile): where a map is farther from the track, the CV has not tested it."""

    sd_scale: float
    model_coverage: float
    coverage: float
    reach_m: float

    @classmethod
    def of(cls, cv: CVResult, folds: np.ndarray, xy: np.ndarray) -> Calibration:
        r = cv.band_ratio
        floor = 1.0 / MAX_SD_SCALE if cv.coverage95 > OVER_COVERAGE else 1.0
        scale = _scale(r, floor)
        covered = np.empty(len(r), bool)
        for f in np.unique(folds):
            test = folds == f
            k = _scale(r[~test], floor) if (~test).any() else scale
            covered[test] = r[test] <= k
        return cls(scale, cv.coverage95, float(covered.mean()), cv_reach(xy, folds))

    def to_json(self) -> dict:
        return {
            k: float(getattr(self, k))
            for k in ("sd_scale", "model_coverage", "coverage", "reach_m")
        }

    @classmethod
    def from_json(cls, d) -> Calibration | None:
        """A saved calibration, or None if it is not one (an older or hand-edited file)."""
        try:
            c = cls(*(float(d[k]) for k in ("sd_scale", "model_coverage", "coverage", "reach_m")))
        except (KeyError, TypeError, ValueError):
            return None
        ok = np.isfinite([c.sd_scale, c.coverage, c.reach_m]).all() and c.sd_scale > 0
        return c if ok else None

    def line(self) -> str:
        """One line for a map: the band's held-out coverage, and by how much it is off 95 %."""
        text = (
            f"the predictive 95 % band covers {self.coverage:.1%} of blocked-CV held-out samples (the "
            f"model's own band {self.model_coverage:.1%}; its sd x {self.sd_scale:.2f} from the CV)"
        )
        if not 0.90 <= self.coverage <= 0.98:
            text += f": {abs(self.coverage - 0.95):.1%} {'under' if self.coverage < 0.95 else 'over'} 95 %"
        return text


def _scale(ratio: np.ndarray, floor: float) -> float:
    if not len(ratio):
        return 1.0
    q = float(np.quantile(ratio, 0.95))
    return float(np.clip(q, floor, MAX_SD_SCALE)) if np.isfinite(q) else MAX_SD_SCALE


def cv_reach(xy: np.ndarray, folds: np.ndarray, quantile: float = REACH_QUANTILE) -> float:
    """How far (m) the held-out samples of `folds` lay from their nearest training sample (the quantile)."""
    from scipy.spatial import cKDTree

    d = np.zeros(len(xy))
    for f in np.unique(folds):
        test = folds == f
        if (~test).any():
            # an unbalanced tree of uncompacted nodes: the same distances, a tenth of the query time on a
            # survey that revisits its ground (a million samples: 0.9 -> 0.1 s a fold)
            tree = cKDTree(xy[~test], balanced_tree=False, compact_nodes=False)
            d[test] = tree.query(xy[test])[0]
    return float(np.quantile(d, quantile)) if len(d) else 0.0


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


def clustered_sd(x: np.ndarray, cluster: np.ndarray) -> float:
    """The sd of the mean of `x` when its values are correlated within each cluster and independent between
    clusters (the sandwich estimator over the clusters' sums); infinite with fewer than two clusters."""
    _, k = np.unique(cluster, return_inverse=True)
    n_clusters = int(k.max()) + 1
    if n_clusters < 2:
        return math.inf
    sums = np.bincount(k.ravel(), weights=x - x.mean())
    return float(np.sqrt((sums * sums).sum() * n_clusters / (n_clusters - 1)) / len(x))


def gain_sd(base_sq: np.ndarray, cand_sq: np.ndarray, groups: np.ndarray) -> float:
    """The sd of `paired_test`'s relative RMSE drop 1 - sqrt(mean(cand_sq) / mean(base_sq)), its errors
    correlated within a group and independent between groups: the delta method on the ratio R of the two
    means, whose linearisation (cand_sq - R base_sq) / mean(base_sq) is summed over the groups (a cluster
    sandwich, as `clustered_sd`)."""
    mb = float(np.mean(base_sq))
    if mb <= 0:
        return math.inf
    ratio = float(np.mean(cand_sq)) / mb
    sd_ratio = clustered_sd((cand_sq - ratio * base_sq) / mb, groups)
    return sd_ratio / (2.0 * math.sqrt(ratio)) if ratio > 0 else math.inf
