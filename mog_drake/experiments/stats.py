"""Honest summary statistics: means with 95 % confidence intervals."""

from __future__ import annotations

import math

import numpy as np


def t975(df: int) -> float:
    """Student's t 97.5 % quantile for ``df`` degrees of freedom (a two-sided 95 % interval)."""
    from scipy.stats import t

    return float(t.ppf(0.975, df))


def mean_ci(values) -> tuple[float, float]:
    """(mean, half-width of the 95 % t confidence interval); half-width nan for n < 2."""
    x = np.asarray(
        [v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))], float
    )
    if len(x) == 0:
        return float("nan"), float("nan")
    if len(x) == 1:
        return float(x[0]), float("nan")
    return float(x.mean()), float(t975(len(x) - 1) * x.std(ddof=1) / math.sqrt(len(x)))


def proportion_ci(k: int, n: int) -> tuple[float, float, float]:
    """(share, low, high): the Wilson 95 % interval of k successes in n trials."""
    if n == 0:
        return float("nan"), float("nan"), float("nan")
    z = 1.96
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return p, max(0.0, centre - half), min(1.0, centre + half)
