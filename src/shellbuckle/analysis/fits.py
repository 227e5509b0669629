"""Power laws of the buckling thresholds across runs, their crossings, and W averages.

Quilliet et al. (EPJE 27, 13 (2008), §4.4, Fig. 10) fit the primary buckling threshold with
``dV/V = 2.8 gamma^-0.55`` and both secondary thresholds (loss of axisymmetry, wrinkles) with
``dV/V = 850 / gamma``; the latter reaches ``dV/V = 1`` at ``gamma_c = 850``, which the paper
compares with its observation that secondary buckling appears between gamma = 583 and 933
(Fig. 5 and §4.2: W averaged over ``dV/V`` in [0.53, 0.76]).

- :func:`fit_power_law` (x, y, sigma=None, exponent=None, bootstrap=0) -> :class:`PowerLawFit`,
  least squares of ``log y = log a + b log x``;
- :func:`gamma_at` (fit, level=1) the ``gamma`` where a law reaches ``dV/V = level``;
  :func:`critical_gamma` the paper's ``gamma_c`` (the secondary law at ``dV/V = 1``);
  :func:`crossover` (fit_primary, fit_secondary) where two laws meet; each with its error;
- :func:`wrinkle_average` (table, window) mean, standard deviation and number of the ``W``
  of the wrinkled steps in a ``dV/V`` window.

Uncertainties are 1-sigma and come from the covariance of ``(ln a, b)``; they are propagated
to derived numbers to first order (delta method).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

log = logging.getLogger(__name__)

#: dV/V window over which W is averaged (Quilliet et al. 2008, Fig. 5).
W_WINDOW = (0.53, 0.76)
#: Central fraction of the bootstrap distribution reported as the interval (1-sigma-like).
BOOTSTRAP_COVERAGE = 0.6827


@dataclass(frozen=True)
class PowerLawFit:
    """``y = prefactor * x ** exponent`` fitted in log-log space.

    ``prefactor_err``, ``exponent_err``: 1-sigma errors (``exponent_err = 0`` when the exponent
    was fixed). ``cov``: covariance of ``(ln prefactor, exponent)`` as a nested tuple, the
    source of every propagated error. ``n``: number of points; ``fixed_exponent``: whether the
    exponent was imposed; ``weighted``: whether ``sigma`` (std of y) set the weights and the
    errors (absolute sigma) rather than the scatter of the residuals; ``residual_std``:
    ``sqrt(sum r_i^2 / (n - p))`` of the log residuals ``r_i = ln y_i - ln(a x_i^b)``
    (``p`` fitted parameters; NaN when ``n = p``). ``prefactor_interval``,
    ``exponent_interval``: central 68.27 % bootstrap intervals when ``bootstrap > 0`` was
    asked for, else None.
    """

    prefactor: float
    exponent: float
    prefactor_err: float
    exponent_err: float
    n: int
    fixed_exponent: bool
    residual_std: float
    cov: tuple = ((math.nan, math.nan), (math.nan, math.nan))
    weighted: bool = False
    prefactor_interval: tuple | None = None
    exponent_interval: tuple | None = None

    def __call__(self, x):
        """``prefactor * x ** exponent`` (vectorized; a float for a scalar)."""
        out = self.prefactor * np.asarray(x, dtype=float) ** self.exponent
        return float(out) if out.ndim == 0 else out

    @property
    def log_prefactor_err(self) -> float:
        """1-sigma error of ``ln prefactor``."""
        return math.sqrt(self.cov[0][0]) if self.cov[0][0] >= 0 else math.nan

    def to_dict(self) -> dict:
        """Plain JSON-able values (tuples as lists)."""
        return {"prefactor": self.prefactor, "exponent": self.exponent,
                "prefactor_err": self.prefactor_err, "exponent_err": self.exponent_err,
                "n": self.n, "fixed_exponent": self.fixed_exponent,
                "residual_std": self.residual_std, "cov": [list(r) for r in self.cov],
                "weighted": self.weighted,
                "prefactor_interval": None if self.prefactor_interval is None
                else list(self.prefactor_interval),
                "exponent_interval": None if self.exponent_interval is None
                else list(self.exponent_interval)}

    @property
    def has_error(self) -> bool:
        """Whether the fit has an error estimate: weighted by the seeds' sigma, or more points
        than parameters (the residual scatter)."""
        return math.isfinite(self.prefactor_err)

    @property
    def n_parameters(self) -> int:
        """Parameters fitted: the prefactor, and the exponent unless it was fixed."""
        return 1 if self.fixed_exponent else 2

    @property
    def dof(self) -> int:
        """Degrees of freedom of the fit, ``n - n_parameters`` (0: the line goes through the
        points and, unweighted, has no error estimate)."""
        return self.n - self.n_parameters

    def describe(self) -> str:
        """:meth:`__str__` with the degrees of freedom and where the errors come from, as a
        figure's legend gives it: ``2.80(±0.15) γ^-0.55(±0.02); 7 points, 5 dof``,
        ``... ; 2 points, 0 dof, errors from the seeds' scatter`` (weighted), or
        ``5.404 γ^-0.587 (no error estimate: 2 point(s) for 2 parameter(s), 0 dof)``."""
        if not self.has_error:
            return str(self)
        source = ", errors from the seeds' scatter" if self.weighted else ""
        return f"{self}; {self.n} points, {self.dof} dof{source}"

    def __str__(self) -> str:
        a = _with_error(self.prefactor, self.prefactor_err)
        note = "" if self.has_error else (f", no error estimate: {self.n} point(s) for "
                                          f"{self.n_parameters} parameter(s), {self.dof} dof")
        if self.fixed_exponent:
            return f"{a} γ^{self.exponent:g} (exponent fixed{note})"
        return f"{a} γ^{_with_error(self.exponent, self.exponent_err)}" + (
            f" ({note[2:]})" if note else "")


def _decimals(err: float) -> int:
    """Decimals that show ``err`` with one significant digit (two when it starts with 1)."""
    first = math.floor(math.log10(err))
    digits = 2 if int(err / 10.0 ** first) == 1 else 1
    return max(0, digits - 1 - first)


def _with_error(value: float, err: float) -> str:
    """``2.80(±0.15)``: the error with one or two significant digits, the value to match."""
    if not (math.isfinite(err) and err > 0):
        return f"{value:.4g}" if not err == 0 else f"{value:.4g}(±0)"
    d = _decimals(err)
    return f"{value:.{d}f}(±{err:.{d}f})"


def _check_data(x, y, sigma, exponent):
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if len(x) != len(y):
        raise ValueError(f"x and y must have the same length, got {len(x)} and {len(y)}")
    need = 1 if exponent is not None else 2
    if len(x) < need:
        raise ValueError(f"a power-law fit needs at least {need} point(s) "
                         f"({'fixed' if exponent is not None else 'free'} exponent), "
                         f"got {len(x)}")
    for name, v in (("x", x), ("y", y)):
        bad = ~(np.isfinite(v) & (v > 0))
        if bad.any():
            raise ValueError(f"a power law is fitted in log-log space: every {name} must be a "
                             f"finite number > 0, got {name}[{int(np.argmax(bad))}] = "
                             f"{v[bad][0]!r}")
    if sigma is not None:
        sigma = np.asarray(sigma, dtype=float).ravel()
        if sigma.shape == (1,):
            sigma = np.full(len(y), sigma[0])
        if len(sigma) != len(y):
            raise ValueError(f"sigma must have one value per point ({len(y)}), got {len(sigma)}")
        bad = ~(np.isfinite(sigma) & (sigma > 0))
        if bad.any():
            raise ValueError(f"sigma (the standard deviation of y) must be finite and > 0, got "
                             f"sigma[{int(np.argmax(bad))}] = {sigma[bad][0]!r}")
    if exponent is not None and not math.isfinite(float(exponent)):
        raise ValueError(f"a fixed exponent must be a finite number, got {exponent!r}")
    if len(x) >= 2 and exponent is None and np.ptp(np.log(x)) == 0:
        raise ValueError("a free exponent needs at least two distinct x values, got "
                         f"x = {x[0]!r} for every point")
    return x, y, sigma


def _solve(lx, ly, w, exponent):
    """Weighted least squares of ``ly = c + b lx``; returns ``(c, b, inv)`` where ``inv`` is
    ``(J^T W J)^-1`` in the ``(c, b)`` parameters (zero row/column for a fixed ``b``)."""
    if exponent is not None:
        b = float(exponent)
        sw = float(w.sum())
        c = float((w * (ly - b * lx)).sum() / sw)
        return c, b, np.array([[1.0 / sw, 0.0], [0.0, 0.0]])
    J = np.column_stack([np.ones_like(lx), lx])
    M = J.T @ (w[:, None] * J)
    c, b = np.linalg.solve(M, J.T @ (w * ly))
    return float(c), float(b), np.linalg.inv(M)


def fit_power_law(x, y, *, sigma=None, exponent=None, bootstrap: int = 0,
                  seed: int = 0) -> PowerLawFit:
    """Fit ``y = a x^b`` by least squares of ``ln y = ln a + b ln x``.

    ``sigma``: standard deviations of ``y`` (one per point, or one for all). Then each point
    weighs ``1/s_i^2`` with ``s_i = sigma_i / y_i`` (the std of ``ln y`` to first order) and
    the covariance is ``(J^T W J)^-1`` (absolute sigma: the errors are what the given sigma
    imply). Without ``sigma`` the points weigh equally and the covariance is scaled by the
    residual variance ``sum r^2 / (n - p)`` (NaN errors with as many points as parameters).
    ``exponent``: fix ``b`` (e.g. -1 for the paper's ``850/gamma``) and fit ``a`` only.
    ``bootstrap``: number of residual-bootstrap refits (seeded with ``seed``): the residuals,
    standardized by ``s_i`` when weighted and inflated by ``sqrt(n/(n - p))``, are resampled
    and added back to the fitted line; the central 68.27 % of the refitted ``a`` and ``b`` give
    ``prefactor_interval`` and ``exponent_interval``.

    ValueError for mismatched lengths, fewer than 2 points (1 with a fixed exponent),
    non-positive or non-finite data, non-positive sigma.
    """
    x, y, sigma = _check_data(x, y, sigma, exponent)
    n = len(x)
    p = 1 if exponent is not None else 2
    lx, ly = np.log(x), np.log(y)
    s = None if sigma is None else sigma / y
    w = np.ones(n) if s is None else 1.0 / s ** 2
    c, b, inv = _solve(lx, ly, w, exponent)
    r = ly - (c + b * lx)
    dof = n - p
    residual_std = math.sqrt(float((r ** 2).sum()) / dof) if dof > 0 else math.nan
    if s is not None:
        cov = inv
    elif dof > 0:
        cov = inv * float((r ** 2).sum()) / dof
    else:
        cov = np.full((2, 2), math.nan)
        if exponent is not None:
            cov[0, 1] = cov[1, 0] = cov[1, 1] = 0.0
        log.info("power-law fit through %d point(s) with %d parameter(s): no residual scatter, "
                 "errors undefined (give sigma)", n, p)
    a = math.exp(c)
    intervals = {}
    if bootstrap:
        intervals = _bootstrap(lx, ly, r, s, exponent, int(bootstrap), seed, c, b)
    return PowerLawFit(
        prefactor=a, exponent=b, prefactor_err=a * math.sqrt(cov[0, 0]) if cov[0, 0] >= 0
        else math.nan, exponent_err=0.0 if exponent is not None else math.sqrt(cov[1, 1])
        if cov[1, 1] >= 0 else math.nan, n=n, fixed_exponent=exponent is not None,
        residual_std=residual_std, cov=tuple(tuple(float(v) for v in row) for row in cov),
        weighted=s is not None, **intervals)


def _bootstrap(lx, ly, r, s, exponent, draws, seed, c, b) -> dict:
    if draws < 0:
        raise ValueError(f"bootstrap must be a number of draws >= 0, got {draws!r}")
    n = len(lx)
    p = 1 if exponent is not None else 2
    if n <= p:
        log.info("bootstrap skipped: %d point(s) for %d parameter(s) leave no residuals", n, p)
        return {}
    rng = np.random.default_rng(seed)
    scale = np.ones(n) if s is None else s
    pool = r / scale * math.sqrt(n / (n - p))
    pool = pool - pool.mean() if s is None else pool
    w = 1.0 / scale ** 2
    fitted = c + b * lx
    cs, bs = np.empty(draws), np.empty(draws)
    for i in range(draws):
        ly_star = fitted + scale * rng.choice(pool, size=n, replace=True)
        cs[i], bs[i], _ = _solve(lx, ly_star, w, exponent)
    q = 100.0 * (1.0 - BOOTSTRAP_COVERAGE) / 2.0
    out = {"prefactor_interval": tuple(float(v) for v in np.exp(np.percentile(cs, [q, 100 - q])))}
    if exponent is None:
        out["exponent_interval"] = tuple(float(v) for v in np.percentile(bs, [q, 100 - q]))
    return out


class Estimate(NamedTuple):
    """A derived number and its 1-sigma error (first-order propagation)."""

    value: float
    err: float


def gamma_at(fit: PowerLawFit, level: float = 1.0) -> Estimate:
    """The ``x`` (gamma) at which ``fit`` equals ``level``: ``(level / a)^(1/b)``.

    With ``u = ln gamma = (ln level - ln a)/b``: ``du/d(ln a) = -1/b``,
    ``du/db = -u/b``, and ``err = gamma * sqrt(g^T C g)`` with ``C = fit.cov``.
    """
    if not (math.isfinite(level) and level > 0):
        raise ValueError(f"level must be a finite number > 0, got {level!r}")
    b = fit.exponent
    if b == 0:
        raise ValueError("a law with exponent 0 is constant: it reaches no particular gamma")
    u = (math.log(level) - math.log(fit.prefactor)) / b
    g = np.array([-1.0 / b, -u / b])
    var = float(g @ np.asarray(fit.cov, float) @ g)
    gamma = math.exp(u)
    return Estimate(gamma, gamma * math.sqrt(var) if var >= 0 else math.nan)


def critical_gamma(fit_secondary: PowerLawFit, level: float = 1.0) -> Estimate:
    """The paper's ``gamma_c``: where the secondary-buckling law reaches ``dV/V = level`` (1,
    the whole volume). Below ``gamma_c`` the secondary threshold would need more volume than
    the shell holds, so shells stay capsules until self-contact (the paper: ``850/gamma`` gives
    ``gamma_c = 850``, between its last capsule-only gamma 583 and its first wrinkled 933).
    Use ``level`` = the self-contact dV/V (about 0.9) for the stricter estimate."""
    return gamma_at(fit_secondary, level)


def crossover(fit_primary: PowerLawFit, fit_secondary: PowerLawFit) -> Estimate:
    """The gamma where two laws meet, ``a1 gamma^b1 = a2 gamma^b2``, with its error.

    ``ln gamma = (ln a2 - ln a1)/(b1 - b2)``; the two fits are independent, so their
    covariances add. Note that the paper's ``gamma_c`` is *not* this: with its laws
    ``2.8 gamma^-0.55`` and ``850/gamma`` the meeting point is at gamma ~ 3e5, far above the
    studied range (the secondary threshold stays above the primary one); ``gamma_c`` is where
    the secondary law reaches ``dV/V = 1`` (:func:`critical_gamma`). Passing a constant law
    (``exponent = 0``, e.g. ``PowerLawFit(1, 0, 0, 0, 1, True, nan)``) as ``fit_primary``
    gives that same number.
    """
    db = fit_primary.exponent - fit_secondary.exponent
    if db == 0:
        raise ValueError("the two laws have the same exponent: they never meet (or always do)")
    u = (math.log(fit_secondary.prefactor) - math.log(fit_primary.prefactor)) / db
    g1 = np.array([-1.0 / db, -u / db])   # d u / d(ln a1, b1)
    g2 = np.array([1.0 / db, u / db])     # d u / d(ln a2, b2)
    var = float(g1 @ np.asarray(fit_primary.cov, float) @ g1
                + g2 @ np.asarray(fit_secondary.cov, float) @ g2)
    gamma = math.exp(u)
    return Estimate(gamma, gamma * math.sqrt(var) if var >= 0 else math.nan)


class WrinkleAverage(NamedTuple):
    """Mean and population standard deviation of W over ``n`` steps (NaN when ``n = 0``)."""

    mean: float
    std: float
    n: int


def wrinkle_average(table, window=W_WINDOW) -> WrinkleAverage:
    """W averaged over the steps of a run table whose ``dV_over_V`` lies in ``window``
    (inclusive) and whose ``shape`` is ``wrinkled`` (the paper's Fig. 5; the standard deviation
    is the population one, as the error bars of the figure).

    ``table`` needs the analysis columns ``shape`` and ``W``
    (:func:`shellbuckle.analysis.analyze_run`); ValueError otherwise.
    """
    lo, hi = (float(v) for v in window)
    if not lo <= hi:
        raise ValueError(f"window must be (low, high) with low <= high, got {window!r}")
    missing = [c for c in ("dV_over_V", "shape", "W") if c not in table.columns]
    if missing:
        raise ValueError(f"the table has no {', '.join(missing)} column(s): analyse the run "
                         "first (`shellbuckle analyze DIR`)")
    dv = table["dV_over_V"].to_numpy(dtype=float)
    chosen = (dv >= lo) & (dv <= hi) & (table["shape"].astype(str).to_numpy() == "wrinkled")
    W = table["W"].to_numpy(dtype=float)[chosen]
    if not len(W):
        return WrinkleAverage(math.nan, math.nan, 0)
    return WrinkleAverage(float(W.mean()), float(W.std()), int(len(W)))
