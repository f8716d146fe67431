#!/usr/bin/env python3
"""Fits the cost constants of the majorant pilot (src/volume/majorant_choice.rs) to measured timings.

    cargo bench --bench majorants -- FILES... --tau 0.1,1,10,100 --rays 5000 --csv | grep ^CSV > costs.csv
    python3 benches/fit_majorant_costs.py costs.csv        # needs numpy

Model: ns per tracked ray = a + NS_PER_CELL * cells + NS_PER_LOOKUP * lookups, one fit over every grid, optical
depth, structure and estimator (free flights and transmittance), least squares on relative error. Only the two
slopes matter to the choice (the intercept is the same for every structure).
"""
import csv
import sys

import numpy as np

rows = [r for r in csv.reader(open(sys.argv[1])) if r and r[0] == "CSV"]
x, y = [], []
for r in rows:
    cells_d, look_d, ns_d, cells_r, look_r, ns_r = map(float, r[4:10])
    for cells, lookups, ns in ((cells_d, look_d, ns_d), (cells_r, look_r, ns_r)):
        x.append([1.0, cells, lookups])
        y.append(ns)
x, y = np.array(x), np.array(y)
w = 1.0 / y
coef, *_ = np.linalg.lstsq(x * w[:, None], y * w, rcond=None)
ratio = (x @ coef) / y
print(f"intercept {coef[0]:.1f} ns, NS_PER_CELL {coef[1]:.1f}, NS_PER_LOOKUP {coef[2]:.1f}")
print(f"predicted/measured over {len(y)} rows: {ratio.min():.2f} .. {ratio.max():.2f}")
