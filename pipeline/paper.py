"""The published figures of Meng et al., Ocean Engineering 294 (2024) 116853, in one place.

Every number the project shows beside its own results comes from here, each with the table (or
section) it is printed in; docs/results.md shows them side by side with the measured ones.  Units
are those of docs/contract.md: parameters a11 a12 a21 a22 in 1/s, b11 b21 in 1/s^2 (the paper's
deg-based rudder input), K 1/s, T's s, MSE v (m/s)^2, MSE r (deg/s)^2, MAE psi deg, times s,
angles deg.

Examples
--------
>>> from pipeline import paper
>>> paper.TABLE7["K"], paper.TABLES_5_6["table5"]["rows"]["srukf-ffm"]["mae_psi"]
(0.3867, 3.55)

Table 7 is Eq. 6 of Table 4 (:func:`pipeline.model.nomoto_indices`) to Table 4's rounding:

>>> from pipeline.model import nomoto_indices
>>> round(nomoto_indices(paper.TABLE4)["K"], 3)
0.387
"""

from __future__ import annotations

#: Where the figures come from.
REFERENCE = "Meng et al., Ocean Engineering 294 (2024) 116853"
#: The ship the paper's figures are for (its tank data): they are for it alone.
SHIP = "KCS"

#: Table 4: the sway-yaw parameters identified by SR-UKF-FFM on the KCS 20/20 zigzag.
TABLE4 = {"a11": -1.882, "a12": -0.1232, "a21": -7.422, "a22": -0.8129, "b11": 0.0099, "b21": 0.1657}

#: Table 7: the Nomoto indices (K 1/s, T1 T2 T3 T s) from Table 4 by Eq. 6.
TABLE7 = {"K": 0.3867, "T1": 3.9688, "T2": 0.4094, "T3": 0.6960, "T": 3.6822}

#: Table 7: K (1/s) and T (s) by the graphical (Nomoto standard test) method.
GRAPHICAL = {"K": 0.576, "T": 4.816}

#: Tables 5 and 6: one-step online prediction errors on the rest of the 20/20 zigzag after the
#: 585-sample window (Table 5) and on the 10/10 zigzag (Table 6).
TABLES_5_6 = {
    "table5": {"validation": "rest of the 20/20 zigzag after 585 samples", "rows": {
        "ffm-ukf": {"mse_v": 0.0152, "mse_r": 1.28, "mae_psi": 4.43},
        "srukf-ffm": {"mse_v": 0.0037, "mse_r": 0.71, "mae_psi": 3.55}}},
    "table6": {"validation": "10/10 zigzag", "rows": {
        "ffm-ukf": {"mse_v": 0.0046, "mse_r": 0.83, "mae_psi": 3.69},
        "srukf-ffm": {"mse_v": 0.0016, "mse_r": 0.49, "mae_psi": 1.95}}},
}

#: The identification time (s) the paper reports for SR-UKF-FFM on the 585-sample window.
IDENT_SECONDS = 0.377
#: The identification window (samples at 0.08 s) the paper's Tables 4-7 use.
IDENT_SAMPLES = 585
#: Rudder angle and heading trigger (deg) of the zigzag the paper identifies on (20/20, to starboard).
IDENT_ZIGZAG_DEG = 20.0

#: The paper's course-keeping simulation with the Table 7 indices (set course 0 -> 60 deg over
#: 200 s, Tw = 3 s, wind as a 2 deg rudder, wave G(s) = 0.2386 s / (s^2 + 0.3593 s + 0.8067)):
#: rise time s, maximum deviation deg, steady MAE deg, rudder angles deg.
CONTROL = {"rise_time": 24.0, "max_deviation": 1.46, "steady_mae": 0.86, "max_rudder_below": 25.0,
           "steady_rudder_min": -3.78, "steady_rudder_max": -1.09, "mean_rudder": -1.70}
