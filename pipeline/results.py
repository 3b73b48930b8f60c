"""A stage's result as a typed, frozen object with its JSON form (docs/api.md#typed-results).

One pattern for every stage's result file: a frozen dataclass deriving from :class:`Result` whose
fields, in declaration order, are the file's keys in the order the file carries them.
:meth:`Result.to_json` gives the JSON-ready dict (written by :func:`pipeline.io.write_json`, which
turns numpy numbers into plain ones); :meth:`Result.from_json` is its inverse for the fields that are
themselves results.  Two field kinds cover the keys a file carries only sometimes:

* :func:`optional` -- a key left out of the file when its value is None;
* :func:`spread` -- a mapping whose keys are written at this place into the parent (e.g. the
  ``virtual_tank`` label of :func:`pipeline.catalog.data_label`).

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Gain(Result):
...     K: float
...     T: float
...     note: str | None = optional()
...     label: dict = spread()
>>> Gain(0.4, 12.0).to_json()
{'K': 0.4, 'T': 12.0}
>>> Gain(0.4, 12.0, note="flagged", label={"virtual_tank": "simulated"}).to_json()
{'K': 0.4, 'T': 12.0, 'note': 'flagged', 'virtual_tank': 'simulated'}
>>> Gain.from_json({'K': 0.4, 'T': 12.0, 'virtual_tank': 'simulated'})
Gain(K=0.4, T=12.0, note=None, label={'virtual_tank': 'simulated'})
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Mapping
from typing import Any

_OMIT = "omit_if_none"
_SPREAD = "spread"


def optional(default: Any = None) -> Any:
    """A field whose key is left out of the JSON when its value is None (default None)."""
    return dataclasses.field(default=default, metadata={_OMIT: True})


def spread() -> Any:
    """A mapping field whose items are written at its place into the parent's JSON (default ``{}``);
    :meth:`Result.from_json` gives it every key no other field reads."""
    return dataclasses.field(default_factory=dict, metadata={_SPREAD: True})


def plain(value: Any) -> Any:
    """``value`` with every :class:`Result` (or object with ``to_json()``) in it replaced by its JSON
    form, mappings as dicts and tuples as lists; other values (numbers, strings, numpy) as they are."""
    if hasattr(value, "to_json"):
        return value.to_json()
    if isinstance(value, Mapping):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value


class Result:
    """Base of the typed results: JSON keys are the dataclass fields, in their declaration order."""

    def to_json(self) -> dict[str, Any]:
        """The JSON-ready dict of this result (keys in field order; see the module docstring)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            if f.metadata.get(_SPREAD):
                out.update(plain(value))
            elif not (f.metadata.get(_OMIT) and value is None):
                out[f.name] = plain(value)
        return out

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]):
        """The result from its JSON form; a field typed as another :class:`Result` is rebuilt with
        that class's ``from_json``.  A missing required key raises KeyError."""
        hints = typing.get_type_hints(cls)
        fields = dataclasses.fields(cls)  # type: ignore[arg-type]
        named = {f.name for f in fields if not f.metadata.get(_SPREAD)}
        kwargs: dict[str, Any] = {}
        for f in fields:
            if f.metadata.get(_SPREAD):
                kwargs[f.name] = {k: v for k, v in doc.items() if k not in named}
                continue
            if f.name not in doc:
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                    raise KeyError(f"{cls.__name__}: key {f.name!r} missing")
                continue
            value = doc[f.name]
            kind = hints.get(f.name)
            if isinstance(kind, type) and issubclass(kind, Result) and value is not None:
                value = kind.from_json(value)
            kwargs[f.name] = value
        return cls(**kwargs)
