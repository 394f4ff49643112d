"""Offline reference values for shared/impedance/tests/it/ftest_scipy.rs.

Run with a Python that has scipy (e.g. a venv made by tools/python/ensure_venv.sh
plus `pip install scipy`); prints the Rust literals pasted into the test.
Not run by the tests: the values are pinned in the test with the scipy call
beside each.
"""
import scipy
from scipy.stats import f

print(f"// scipy {scipy.__version__}")
DOFS = [(1, 1), (1, 10), (2, 5), (3, 7), (9, 144), (10, 160), (90, 1440), (5, 100000), (200, 3)]
XS = [0.01, 0.3, 1.0, 2.5, 4.13, 20.0, 73.0]
print("// (d1, d2, x, scipy.stats.f.sf(x, d1, d2), scipy.stats.f.cdf(x, d1, d2))")
for d1, d2 in DOFS:
    for x in XS:
        if f.sf(x, d1, d2) == 0.0:
            continue  # underflows: no relative comparison possible
        print(f"    ({d1}.0, {d2}.0, {x!r}, {float(f.sf(x, d1, d2))!r}, {float(f.cdf(x, d1, d2))!r}),")
LEVELS = [0.999, 0.9, 0.5, 0.05, 0.01, 1e-4]
print("// (d1, d2, level, scipy.stats.f.isf(level, d1, d2) == f.ppf(1 - level, d1, d2))")
for d1, d2 in DOFS:
    for a in LEVELS:
        print(f"    ({d1}.0, {d2}.0, {a!r}, {float(f.isf(a, d1, d2))!r}),")

# Nested F-tests computed by hand in the test (see ftest_scipy.rs).
print("// nested cases")
for x, d1, d2 in [(6.0, 2, 36), (3.2, 9, 144)]:
    print(f"    f.sf({x}, {d1}, {d2}) = {float(f.sf(x, d1, d2))!r}; f.isf(0.05, {d1}, {d2}) = {float(f.isf(0.05, d1, d2))!r}; f.isf(0.01, {d1}, {d2}) = {float(f.isf(0.01, d1, d2))!r}")

# Student's t quantile of the fit's 95 % intervals, chi-squared survival.
from scipy.stats import t, chi2
print("// (dof, scipy.stats.t.ppf(0.975, dof))")
for dof in [1, 2, 3, 5, 14, 16, 30, 511, 512, 2000]:
    print(f"    ({dof}, {float(t.ppf(0.975, dof))!r}),")
print("// (x, dof, scipy.stats.chi2.sf(x, dof))")
for x, dof in [(0.5, 1), (3.0, 2), (16.0, 16), (40.0, 16), (150.0, 100), (5.0, 30)]:
    print(f"    ({x!r}, {dof}, {float(chi2.sf(x, dof))!r}),")

# ftest_inputs.rs: a nested test adding three parameters (p_r = 1, p_f = 4).
print(f"    f.sf(2.0, 6, 32) = {float(f.sf(2.0, 6, 32))!r}; f.isf(0.05, 6, 32) = {float(f.isf(0.05, 6, 32))!r}")
