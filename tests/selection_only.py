"""The diagnosis setting of tests that assert the selection and its findings only.

The honest gain's nested leave-one-run-out does not change them
(test_diagnose.py::test_nested_workers_give_the_same_report_bytes compares every key of the report)
and takes two thirds of a 4-run diagnosis, so those tests switch it off.  It stays on, and is
asserted, where it is the subject: the KVLCC2 side-swap folds, the catalog-mode and CLI contract
tests.  The reference fit (DiagnoseConfig.reference_fit) is reported beside the selection and does not
change it either, so they switch it off too."""

from pipeline.config import DiagnoseConfig

SELECTION_ONLY = DiagnoseConfig(nested_gain=False, reference_fit=False)
