"""Ingest stage: raw tank files to validated, resampled runs (docs/contract.md, docs/dataset.md).

Public API (other stages code against these names):

- :func:`read_raw` (path, fmt=None, scale=None, config) -> Run at the original sampling, canonical units
- :func:`resample` (run, dt) -> Run on a uniform grid, anti-aliased
- :func:`ingest_file` (path, fmt=None, scale=None, config) -> read_raw + resample
- :func:`detect_format`, :data:`FORMATS`; :func:`parse_raw` (the same as read_raw, on bytes or text)
"""

from pipeline.ingest.core import ingest_file, lowpass, parse_raw, read_raw, resample, with_dt
from pipeline.ingest.formats import FORMATS, detect_format

__all__ = ["FORMATS", "detect_format", "ingest_file", "lowpass", "parse_raw", "read_raw", "resample",
           "with_dt"]
