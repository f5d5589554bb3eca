"""ROC and AUC of a grasp measure (S_G, lower is better) as a predictor of a physical hold.

Computed with numpy (no scikit-learn): the AUC is the Mann-Whitney probability that a held grasp
has a lower S_G than a dropped one (ties count one half); an infeasible S_G counts as the worst.
The best-separating threshold maximises Youden's J = TPR - FPR over the observed S_G values,
predicting "holds" for S_G <= threshold.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Roc:
    """ROC of "S_G <= t predicts a hold" over the tested grasps."""

    fpr: np.ndarray
    tpr: np.ndarray
    thresholds: np.ndarray
    auc: float
    best_threshold: float
    best_j: float
    positives: int
    negatives: int


def sg_for_ranking(s_g: Sequence[float | None]) -> np.ndarray:
    """S_G with an infeasible grasp (None) as +inf."""
    return np.array([np.inf if s is None else float(s) for s in s_g])


def auc_mann_whitney(held: np.ndarray, dropped: np.ndarray) -> float:
    """P(S_G of a held grasp < S_G of a dropped one) + 0.5 P(equal), from ranks."""
    from scipy.stats import rankdata

    n1, n0 = len(held), len(dropped)
    if n1 == 0 or n0 == 0:
        return float("nan")
    ranks = rankdata(np.concatenate([-held, -dropped]))  # higher rank = lower S_G
    u = ranks[:n1].sum() - n1 * (n1 + 1) / 2.0
    return float(u / (n1 * n0))


def roc(s_g: Sequence[float | None], held: Sequence[bool]) -> Roc:
    """The ROC curve, AUC and best (Youden) threshold; see the module docstring."""
    s = sg_for_ranking(s_g)
    y = np.asarray(held, dtype=bool)
    pos, neg = int(y.sum()), int((~y).sum())
    finite = np.unique(s[np.isfinite(s)])
    thresholds = np.concatenate([[-np.inf], finite, [np.inf]])
    tpr = np.array([(s[y] <= t).sum() / max(pos, 1) for t in thresholds])
    fpr = np.array([(s[~y] <= t).sum() / max(neg, 1) for t in thresholds])
    j = tpr - fpr
    k = int(np.argmax(j[1:-1])) + 1 if len(thresholds) > 2 else 0
    return Roc(
        fpr,
        tpr,
        thresholds,
        auc_mann_whitney(s[y], s[~y]),
        float(thresholds[k]),
        float(j[k]),
        pos,
        neg,
    )


def rates_at(s_g: Sequence[float | None], held: Sequence[bool], t: float) -> tuple[float, float]:
    """(TPR, FPR) of "S_G <= t predicts a hold"."""
    s = sg_for_ranking(s_g)
    y = np.asarray(held, dtype=bool)
    tp = float((s[y] <= t).mean()) if y.any() else float("nan")
    fp = float((s[~y] <= t).mean()) if (~y).any() else float("nan")
    return tp, fp
