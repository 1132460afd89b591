"""The spec language's common types: names, strict numbers, object and task references, and the base of every
model (unknown keys are errors, models are frozen)."""

from __future__ import annotations

import math
import re
from typing import Annotated

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field, Strict

from netcfg.spec.names import check_name
from netcfg.spec.units import Duration

Name = Annotated[str, AfterValidator(check_name)]



def _no_bool(value: object) -> object:
    if isinstance(value, bool):
        raise ValueError(f"expected a number, not {str(value).lower()}")
    return value



def _finite(value: float) -> float:
    if not math.isfinite(value):
        raise ValueError(f"expected a finite number, not {value}")
    return value



def _non_zero(value: float) -> float:
    if value == 0:
        raise ValueError("a scale of 0 would map every raw value to the offset; use a non-zero scale")
    return value


# YAML reads yes/no/true/false as booleans: never let them pass for numbers (or numbers for booleans).
Int = Annotated[int, Strict()]


Float = Annotated[float, BeforeValidator(_no_bool), AfterValidator(_finite)]


Bool = Annotated[bool, Strict()]



def _int_key(value: object) -> object:
    """Mapping keys reach the model as text (YAML's `0:`, JSON's "0"): whole numbers only, no booleans."""
    if isinstance(value, str) and re.fullmatch(r"-?[0-9]{1,20}", value.strip()):
        return int(value)
    return value


IntKey = Annotated[int, BeforeValidator(_int_key), Strict()]


# "node.task" references to tasks; flows and triggers use them.
TaskRef = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*\.[A-Za-z][A-Za-z0-9_]*$")]


ObjectRef = Annotated[
    Int | str,
    Field(description="a device object: 0x6064 (sub-index 0) or '0x30D1:2' (index:sub-index)"),
]



class SpecModel(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, defer_build=True)


def _ns(ns: int) -> Duration:
    return Duration(ns=ns)
