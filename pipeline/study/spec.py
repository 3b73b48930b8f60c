"""Study spec files (TOML): ``[study]`` (pipeline.config.StudyConfig) and one table named after the
kind (that kind's settings dataclass).  Unknown keys, wrong types, numbers that are not finite and
values no case could run with (the kind's ``check``) are refused with one line naming the file and the
key, before anything runs."""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pipeline.config import StudyConfig
from pipeline.errors import InputError


@dataclass(frozen=True)
class Spec:
    study: StudyConfig
    settings: Any                     # the kind's settings dataclass
    path: str = "<spec>"


def _coerce(value: Any, hint: Any, where: str, file: str) -> Any:
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        if value is None and type(None) in args:
            return None
        for a in args:
            if a is type(None):
                continue
            try:
                return _coerce(value, a, where, file)
            except InputError:
                continue
        raise InputError(f"key '{where}': {value!r} is not a {hint}", file=file)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise InputError(f"key '{where}': expected a list, got {value!r}", file=file)
        item = args[0] if args else Any
        return tuple(_coerce(v, item, f"{where}[{i}]", file) for i, v in enumerate(value))
    if origin is dict:
        if not isinstance(value, dict):
            raise InputError(f"key '{where}': expected a table, got {value!r}", file=file)
        vt = args[1] if len(args) == 2 else Any
        return {str(k): _coerce(v, vt, f"{where}.{k}", file) for k, v in value.items()}
    if hint is Any:
        return value
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InputError(f"key '{where}': expected a number, got {value!r}", file=file)
        if not math.isfinite(value):      # every number of a study is a physical setting or a rate
            raise InputError(f"key '{where}': expected a finite number, got {value!r}", file=file)
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise InputError(f"key '{where}': expected an integer, got {value!r}", file=file)
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise InputError(f"key '{where}': expected true or false, got {value!r}", file=file)
        return value
    if hint is str:
        if not isinstance(value, str):
            raise InputError(f"key '{where}': expected a string, got {value!r}", file=file)
        return value
    return value


def build(cls: type, table: dict[str, Any], section: str, file: str) -> Any:
    """Instance of dataclass ``cls`` from a TOML table, with types checked and coerced."""
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(table) - names)
    if unknown:
        raise InputError(f"unknown key '{section}.{unknown[0]}' (known: {', '.join(sorted(names))})",
                         file=file)
    kw = {k: _coerce(v, hints[k], f"{section}.{k}", file) for k, v in table.items()}
    return cls(**kw)


#: bytes below which a local worker's ``memory_limit`` is refused: a worker with the study modules
#: loaded measured 276 MiB, and 379 MiB after one KCS autopilot case; dask pauses a worker at 80 % of
#: its limit and kills it at 95 %, so under 512 MiB every case would end in a killed worker
MIN_WORKER_MEMORY = 512 * 2**20


def _check_memory_limit(value: str, file: str) -> None:
    """Refuse a ``study.memory_limit`` that is not a size or that no worker can run a case in."""
    if value == "auto":
        return
    from dask.utils import parse_bytes

    try:
        n = parse_bytes(value)
    except (ValueError, TypeError):
        raise InputError(f"key 'study.memory_limit': {value!r} is not a size (e.g. \"2GiB\", or \"auto\")",
                         file=file) from None
    if 0 < n < MIN_WORKER_MEMORY:          # 0: dask's "no limit"
        raise InputError(f"key 'study.memory_limit': {value} is below the {MIN_WORKER_MEMORY // 2**20} MiB a "
                         "worker needs to run one case (dask kills a worker at 95 % of its limit)", file=file)


def load_spec(path: str | Path) -> Spec:
    """Read and check a study spec file (docs/studies.md).

    Parameters
    ----------
    path : str or Path
        The spec's TOML file.

    Returns
    -------
    Spec
        Its ``[study]`` settings and its kind's typed settings.

    Raises
    ------
    InputError
        The file is missing, not valid TOML, or a table or value is wrong (one line naming the file
        and the key).
    """
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise InputError("study spec not found", file=path) from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML ({exc})", file=path) from None
    return spec_from_dict(doc, str(path))


def spec_from_dict(doc: dict[str, Any], file: str = "<spec>") -> Spec:
    from pipeline.study import get_kind

    if "study" not in doc:
        raise InputError("missing [study] table (with at least kind = ...)", file=file)
    study = build(StudyConfig, doc["study"], "study", file)
    if study.workers < 1:
        raise InputError("key 'study.workers': must be at least 1", file=file)
    if study.retries < 0:
        raise InputError("key 'study.retries': must be 0 or more", file=file)
    _check_memory_limit(study.memory_limit, file)
    if not study.no_worker_timeout_s > 0:
        raise InputError("key 'study.no_worker_timeout_s': must be > 0 s", file=file)
    try:
        kind = get_kind(study.kind)
    except InputError as exc:
        raise InputError(f"key 'study.kind': {exc}", file=file) from None
    extra = sorted(set(doc) - {"study", kind.name})
    if extra:
        raise InputError(f"unknown table [{extra[0]}] for a {kind.name} study", file=file)
    settings = build(kind.config, doc.get(kind.name, {}), kind.name, file)
    if kind.check is not None:
        try:
            kind.check(settings)
        except InputError as exc:
            raise InputError(exc.message, file=file) from None
    return Spec(study=study, settings=settings, path=file)
