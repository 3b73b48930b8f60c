"""Independent test truths for the diagnosis (docs/diagnosis.md).

Plain test helpers, deliberately NOT written in the diagnosis method's own formulas and not
importing ``pipeline.model`` or ``pipeline.diagnose``:

- :mod:`truths.swayyaw`: a continuous-time sway-yaw ship (RK4 at 0.01 s, logged at 0.08 s) with a
  rate-limited rudder servo, zigzag logic on the measured heading and injectable effects in forms
  of their own (servo lag, r|r| and r^3 damping, v|v|, cross terms, stall, asymmetry, offset, speed
  loss with speed-scaled coefficients, AR(1) sensor noise, rudder encoder quantisation), for two
  ships that are not the paper's (a fast, strongly stable one and a slow, nearly course-unstable
  full form);
- :mod:`truths.kvlcc2`: a 3-DOF MMG model of the KVLCC2 (Yasukawa & Yoshimura 2015) at full scale,
  written as MARIN SIMMAN ``.dat`` files (the stand-in for measured data of another ship and tank);
- :mod:`truths.mariner`: the Mariner's Abkowitz model (Chislett & Stroem-Tejsen 1965), full scale;
- :mod:`truths.tanker`: the Van Berlekom & Goddard (1972) large tanker, full scale, course-unstable
  when linear;
- :mod:`truths.files`: writers of raw files in the formats of docs/contract.md#raw-formats (canonical CSV,
  MARIN .dat);
- :mod:`truths.cases`: the seeded cases of tests/test_diagnose_generalise.py and how they are judged;
- ``run_cases.py``: runs every case and prints a table for the lead.

Units and signs everywhere are docs/contract.md#run-data's: time s, v m/s positive to starboard, r deg/s,
psi deg, delta deg with positive delta making r positive, u m/s, model scale unless a function
says full scale.
"""
