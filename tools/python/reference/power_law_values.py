"""Offline reference values for shared/impedance/tests/it/power_law_numpy.rs.

The power law log10 H = beta0 + beta1 log10 K by numpy's least squares
(numpy.linalg.lstsq on the design [1, log10 K]), its R^2 = 1 - RSS/TSS on
the log scale and the standard errors sqrt(s^2 (X^T X)^-1_ii), s^2 =
RSS/(n - 2), from numpy's matrix inverse (not the closed-form sums the
crate uses). Run with the venv of tools/python/ensure_venv.sh; prints the
literals pasted into the test. Not run by the tests.
"""
import numpy as np

print(f"// numpy {np.__version__}")
K = np.array([20.0, 35.0, 60.0, 110.0, 180.0])
H = np.array([5.1, 7.9, 13.0, 20.5, 33.0])
x, y = np.log10(K), np.log10(H)
X = np.stack([np.ones_like(x), x], axis=1)
beta, *_ = np.linalg.lstsq(X, y, rcond=None)
r = y - X @ beta
rss = float(r @ r)
tss = float(((y - y.mean()) ** 2).sum())
cov = rss / (len(x) - 2) * np.linalg.inv(X.T @ X)
print(f"beta0 = {float(beta[0])!r}, beta1 = {float(beta[1])!r}")
print(f"r2 = {1 - rss / tss!r}")
print(f"se0 = {float(np.sqrt(cov[0, 0]))!r}, se1 = {float(np.sqrt(cov[1, 1]))!r}")
