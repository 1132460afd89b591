"""The spec language's reference page, generated from its pydantic models (netcfg/spec/schema.py).

Every key of every model, in the order the models declare them, with its type, unit, default, range and description,
read from the models themselves: a field added, renamed or re-described there shows here at the next build.
"""

from __future__ import annotations

import types
import typing
from typing import Any, Literal, Union, get_args, get_origin

import annotated_types
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

from netcfg.spec import schema, units

# Units the models leave to their descriptions: an integer or number whose unit no type carries. A key that no
# longer exists stops the build (see _check_units), so this table cannot drift from the models silently.
UNITS = {
    "Bus.clock_tolerance": "ppm",
    "FttParams.tm_size": "bytes",
    "SwitchPort.cable": "m",
    "Switch.queue": "frames",
    "SwitchPort.queue": "frames",
    "Node.nic_queue": "frames",
    "TxQueue.depth": "frames",
    "Message.size": "bytes",
    "Signal.bits": "bits",
    "Signal.start_bit": "bit",
    "ErrorModel.burst": "errors",
}

TIME_UNITS = "`ns`, `us`, `ms`, `s`; `EC` on FTT-CAN"
# The unit-bearing field types, known by the parser each one validates with (netcfg/spec/fields.py).
PARSERS = {
    units.parse_duration: ("time", TIME_UNITS),
    units.parse_offset: ("time or `auto`", TIME_UNITS),
    units.parse_bitrate: ("bit rate", "`bit/s`, `kbit/s`, `Mbit/s`, `Gbit/s`, short `k`, `M`, `G`"),
    units.parse_frequency: ("frequency", "`Hz`, `kHz`, `MHz`"),
}
PLAIN = {int: "integer", float: "number", bool: "boolean", str: "text"}


def _section_id(model: type[BaseModel]) -> str:
    return model.__name__.lower()


class _Type:
    """What one annotation says: its words, its unit, and the models it leads to."""

    def __init__(self) -> None:
        self.unit = ""
        self.models: list[type[BaseModel]] = []

    def words(self, annotation: Any, metadata: tuple[Any, ...] = ()) -> str:
        for item in metadata:
            accepted = getattr(item, "json_schema_input_type", PydanticUndefined)
            if accepted not in (PydanticUndefined, Any):  # a validator that reads a shorter form too
                return self.words(accepted)
            func = getattr(item, "func", None)
            if func in PARSERS:
                kind, self.unit = PARSERS[func]
                return kind
            if func is schema.check_name:
                return "name"
        origin = get_origin(annotation)
        if origin is typing.Annotated:
            base, *extra = get_args(annotation)
            return self.words(base, (*metadata, *extra))
        if origin in (Union, types.UnionType):
            options = [a for a in get_args(annotation) if a is not type(None)]
            return " or ".join(self.words(a, metadata) for a in options)
        if origin is Literal:
            return "one of " + ", ".join(f"`{_yaml(v)}`" for v in get_args(annotation))
        if origin is list:
            return f"list of {self.words(get_args(annotation)[0])}"
        if origin is tuple:
            return "[" + ", ".join(self.words(a) for a in get_args(annotation)) + "]"
        if origin is dict:
            key, value = get_args(annotation)
            return f"mapping of {self.words(key)} to {self.words(value)}"
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            self.models.append(annotation)
            return f"[{_title(annotation)}](#{_section_id(annotation)})"
        if annotation in PLAIN:
            return PLAIN[annotation]
        return f"`{getattr(annotation, '__name__', annotation)}`"


def _title(model: type[BaseModel]) -> str:
    return model.__name__


def _yaml(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    return str(value)


def _default(name: str, field: FieldInfo) -> str:
    if field.default_factory is not None:
        value = field.default_factory()  # type: ignore[call-arg]
    elif field.default is PydanticUndefined:
        return "**required**"
    else:
        value = field.default
    if value is None:
        return "—"
    if isinstance(value, BaseModel):
        return "`{" + ", ".join(f"{k}: {_yaml(v)}" for k, v in value.model_dump().items()) + "}`"
    if isinstance(value, list):
        return "`[]`" if not value else f"`{value}`"
    if isinstance(value, int) and not isinstance(value, bool):
        return f"`{_number(name, value)}`".replace(",", "")
    return f"`{_yaml(value)}`"


def _bounds(name: str, metadata: list[Any]) -> str:
    words = []
    for item in metadata:
        if isinstance(item, annotated_types.Ge):
            words.append(f"≥ {_number(name, item.ge)}")
        elif isinstance(item, annotated_types.Gt):
            words.append(f"> {_number(name, item.gt)}")
        elif isinstance(item, annotated_types.Le):
            words.append(f"≤ {_number(name, item.le)}")
        elif isinstance(item, annotated_types.Lt):
            words.append(f"< {_number(name, item.lt)}")
        elif isinstance(item, annotated_types.MinLen) and item.min_length:
            words.append(f"at least {item.min_length}")
        elif isinstance(item, annotated_types.MaxLen):
            words.append(f"at most {item.max_length} characters")
        elif getattr(item, "pattern", None):
            words.append(f"matches `{item.pattern}`")
    return ", ".join(words)


# Identifiers and object indexes read in hexadecimal, as CiA 301 and the CAN tools write them.
HEX_FIELDS = frozenset({"id", "index", "sub", "sync_id", "sync_id_base", "tm_id"})


def _number(name: str, value: Any) -> str:
    if isinstance(value, int) and name in HEX_FIELDS and value > 9:
        return f"0x{value:X}"
    return f"{value:,}" if isinstance(value, int) else f"{value:g}"


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _models() -> list[tuple[str, type[BaseModel]]]:
    """Every model reachable from Spec, each with the first key path that leads to it, breadth first."""
    seen: dict[type[BaseModel], str] = {schema.Spec: ""}
    queue: list[type[BaseModel]] = [schema.Spec]
    while queue:
        model = queue.pop(0)
        for name, field in model.model_fields.items():
            typ = _Type()
            typ.words(field.annotation, tuple(field.metadata))
            key = field.alias or name
            for child in typ.models:
                if child not in seen:
                    seen[child] = f"{seen[model]}.{key}{'[]' if _is_list(field.annotation) else ''}".lstrip(".")
                    queue.append(child)
    return [(path, model) for model, path in seen.items()]


def _is_list(annotation: Any) -> bool:
    if get_origin(annotation) in (Union, types.UnionType):
        return any(_is_list(a) for a in get_args(annotation))
    return get_origin(annotation) is list


def _check_units() -> None:
    for key in UNITS:
        model_name, field = key.split(".")
        model = getattr(schema, model_name, None)
        if model is None or field not in model.model_fields:
            raise SystemExit(f"docs/gen/spec_reference.py: UNITS names {key}, which the spec language no longer has")


def spec_reference() -> str:
    """The generated part of the spec language's reference page, as Markdown."""
    _check_units()
    out: list[str] = []
    for path, model in _models():
        heading = f"`{path}`" if path else "The spec file"
        out.append(f"### {heading} {{#{_section_id(model)}}}\n")
        doc = model.__doc__
        if doc and model is not schema.Spec:
            out.append(" ".join(doc.split()) + "\n")
        out.append("| key | type | unit | default | range | description |")
        out.append("|---|---|---|---|---|---|")
        for name, field in model.model_fields.items():
            typ = _Type()
            words = typ.words(field.annotation, tuple(field.metadata))
            unit = typ.unit or UNITS.get(f"{model.__name__}.{name}", "")
            description = field.description or _inner_description(field.annotation) or ""
            bounds = _bounds(name, list(field.metadata) + _inner_metadata(field.annotation))
            out.append(
                f"| `{field.alias or name}` | {_cell(words)} | {unit} | {_default(name, field)} | {_cell(bounds)} "
                f"| {_cell(description)} |"
            )
        out.append("")
    return "\n".join(out)


def _inner_metadata(annotation: Any) -> list[Any]:
    """Constraints written on an optional field's own type (`Int | None = Field(None, ge=1)` keeps them outside;
    an Annotated alias such as TaskRef keeps them inside)."""
    found: list[Any] = []
    if get_origin(annotation) is typing.Annotated:
        found += [m for m in get_args(annotation)[1:] if isinstance(m, FieldInfo) for m in m.metadata]
        found += _inner_metadata(get_args(annotation)[0])
    elif get_origin(annotation) in (Union, types.UnionType):
        for arg in get_args(annotation):
            found += _inner_metadata(arg)
    return found


def _inner_description(annotation: Any) -> str | None:
    if get_origin(annotation) is typing.Annotated:
        for item in get_args(annotation)[1:]:
            if isinstance(item, FieldInfo) and item.description:
                return item.description
        return _inner_description(get_args(annotation)[0])
    if get_origin(annotation) in (Union, types.UnionType, list):
        for arg in get_args(annotation):
            found = _inner_description(arg)
            if found:
                return found
    return None


if __name__ == "__main__":
    print(spec_reference())
