"""Actuator device profiles: files that describe an actuator's own CAN protocol, checked and turned into the plain
data netcfg.runtime.actuators encodes and decodes with.

A profile is one YAML file: built in (devices/actuators/*.yaml, each naming the vendor document it was written from)
or the user's own, loaded like a vendor EDS. Every problem is reported at its file:line:col; what the format cannot
say (checksums, rolling counters, register subframes chosen at run time, multi-frame transfers, identifiers that need
carries or masks) is refused with the reason, never read approximately. docs/how-to/actuator-profile.md describes the
format; `plain` is the form the runtime reads (netcfg.runtime.actuators' docstring).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from netcfg.devices import builtin_names, builtin_text
from netcfg.devices.actuator_ids import IdRuleError, parse_id_rule
from netcfg.devices.actuator_ros2 import check_ros2_control
from netcfg.diagnostics import Collector, Position, SpecError
from netcfg.links import LINKS
from netcfg.runtime.actuators import SI_UNITS
from netcfg.runtime.codec import byte_ops
from netcfg.spec.source import SourceMap, load_yaml
from netcfg.spec.suggest import did_you_mean

FORMAT = 1
CAN_LINKS = tuple(name for name, link in LINKS.items() if link.arbitrates)  # an actuator profile's `link:`
CAN_FD_SIZES = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)
_NAME = re.compile(r"^[a-z_][a-z0-9_]*$")

TOP_KEYS = ("profile", "format", "vendor", "product", "source", "link", "parameters", "messages", "notes", "enable",
            "safe_stop", "ros2_control")
# what a live master sends an actuator before its cycle (enable) and to bring it to rest (safe_stop): a host message
# of the profile with its fields' values, and the value names the device's state fields report after it
ACTION_KEYS = ("message", "values", "state", "doc")
SOURCE_KEYS = ("document", "version", "url", "sections")
PARAM_KEYS = ("default", "min", "max", "unit", "doc")
MESSAGE_KEYS = ("from", "id", "extended", "size", "fd", "pad", "data", "remote", "fields", "reply", "cyclic", "doc")
REPLY_KEYS = ("message", "delay_us", "basis", "note")
FIELD_KEYS = ("start_bit", "bits", "byte_order", "type", "encoding", "scale", "offset", "range", "value", "unit",
              "role", "flags", "choices", "error_values", "doc")
# what vendors' protocols do that a profile cannot say, and why: a key naming one is refused with its reason
UNREPRESENTABLE = {
    "checksum": "frames with a checksum or CRC over their payload are not representable: the codec writes fields, "
                "not functions of them",
    "crc": "frames with a checksum or CRC over their payload are not representable",
    "counter": "rolling counters (a field that changes every frame) are not representable: the codec is stateless",
    "mux": "multiplexed layouts are written as one message per variant, each with its selector as a constant "
           "field (value:)",
    "multiplexer": "multiplexed layouts are written as one message per variant, each with its selector as a constant "
                   "field (value:)",
    "subframes": "register subframes chosen at run time (moteus' multiplex protocol) are not representable: write "
                 "each register set and resolution you use as a message of its own with constant headers",
    "registers": "register subframes chosen at run time are not representable: write each register set you use as a "
                 "message of its own",
    "segmented": "multi-frame transfers (segmented or ISO-TP) are not representable: a profile message is one frame",
    "sequence": "multi-frame transfers are not representable: a profile message is one frame",
    "variable_size": "frames whose length depends on their content are not representable: give each length as a "
                     "message of its own",
    "formula": "a field computed from other fields is not representable: a field's value is its own raw bits "
               "(linear or span encoded)",
}


@dataclass(frozen=True)
class ActuatorProfile:
    name: str
    source: str  # "builtin:<name>" or the file as given
    document: str  # the vendor document and version it was written from
    plain: dict[str, Any]  # what netcfg.runtime.actuators.ActuatorCodec reads
    # the vendor's ros2_control plugin (netcfg.devices.actuator_ros2), None: it has none; not in `plain`, as a
    # master does not need it
    ros2_control: dict[str, Any] | None = None

    def message_names(self, sender: str | None = None) -> list[str]:
        return [m["name"] for m in self.plain["messages"] if sender is None or m["from"] == sender]


def builtin_actuator_names() -> list[str]:
    return builtin_names("actuators")


@cache
def builtin_actuator_profile(name: str) -> ActuatorProfile:
    """A built-in profile by name; KeyError for an unknown one."""
    return parse_actuator_profile(builtin_text("actuators", name), f"builtin:{name}")


def load_actuator_profile(path: str | Path) -> ActuatorProfile:
    """A user's profile file; SpecError with every problem at its file:line:col."""
    text = Path(path).read_text(encoding="utf-8")
    return parse_actuator_profile(text, str(path))


def parse_actuator_profile(text: str, file: str) -> ActuatorProfile:
    diags = Collector()
    if not text.strip():
        diags.add("profile-empty", "the profile is empty; start with 'profile: <name>' and 'format: 1'",
                  Position(file, 1, 1))
        raise SpecError(diags.items)
    data, smap = load_yaml(text.removeprefix("\ufeff"), file, diags)
    diags.raise_if_errors()
    plain = _Checker(file, smap, diags).profile(data)
    diags.raise_if_errors()
    assert plain is not None
    src = plain.get("source", {})
    document = f"{src.get('document', '?')}, {src.get('version', '?')}"
    ros2 = plain.pop("ros2_control", None)
    return ActuatorProfile(plain["name"], file, document, plain, ros2)


class _Checker:
    def __init__(self, file: str, smap: SourceMap, diags: Collector) -> None:
        self.file, self.smap, self.d = file, smap, diags

    def err(self, code: str, message: str, path: tuple[str | int, ...], key: bool = False) -> None:
        self.d.add(code, message, self.smap.key_at(path) if key else self.smap.at(path))

    def keys(self, data: dict[str, Any], known: tuple[str, ...], path: tuple[str | int, ...], what: str) -> None:
        for k in data:
            if k in known:
                continue
            if k in UNREPRESENTABLE:
                self.err("profile-unrepresentable", f"'{k}' in {what}: {UNREPRESENTABLE[k]}", (*path, k), key=True)
            else:
                self.err("profile-key", f"unknown key '{k}' in {what}{did_you_mean(k, known)}; known: "
                         f"{', '.join(known)}", (*path, k), key=True)

    def mapping(self, value: Any, path: tuple[str | int, ...], what: str) -> dict[str, Any] | None:
        if isinstance(value, dict):
            return value
        self.err("profile-type", f"{what} must be a mapping, not {type(value).__name__}", path)
        return None

    def integer(self, value: Any, path: tuple[str | int, ...], what: str, low: int, high: int) -> int | None:
        if type(value) is not int:
            self.err("profile-type", f"{what} must be a whole number, not {value!r}", path)
            return None
        if not low <= value <= high:
            self.err("profile-range", f"{what} = {value} is outside {low}..{high}", path)
            return None
        return value

    def number(self, value: Any, path: tuple[str | int, ...], what: str) -> float | int | None:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.err("profile-type", f"{what} must be a number, not {value!r}", path)
            return None
        return value

    def choice(self, value: Any, options: tuple[Any, ...], path: tuple[str | int, ...], what: str) -> Any:
        if value in options and type(value) is type(options[options.index(value)]):
            return value
        words = ", ".join(str(o).lower() if isinstance(o, bool) else str(o) for o in options)
        self.err("profile-value", f"{what} must be one of {words}, not {value!r}"
                 + (did_you_mean(value, [str(o) for o in options]) if isinstance(value, str) else ""), path)
        return None

    def text(self, value: Any, path: tuple[str | int, ...], what: str) -> str | None:
        if isinstance(value, str) and value.strip():
            return value
        self.err("profile-type", f"{what} must be text, not {value!r}", path)
        return None

    # -- the file
    def profile(self, data: Any) -> dict[str, Any] | None:
        top = self.mapping(data, (), "a profile")
        if top is None:
            return None
        self.keys(top, TOP_KEYS, (), "the profile")
        for required in ("profile", "format", "source", "messages"):
            if required not in top:
                self.d.add("profile-missing", f"the profile has no '{required}'", Position(self.file, 1, 1))
        if "format" in top and top["format"] != FORMAT:
            self.err("profile-format", f"format {top['format']!r} is not one netcfg reads; this netcfg reads format "
                     f"{FORMAT}", ("format",))
        name = top.get("profile")
        if name is not None and not (isinstance(name, str) and re.match(r"^[a-z0-9][a-z0-9._-]*$", name)):
            self.err("profile-name", f"the profile name must be lower-case words joined by '-' (as a spec's "
                     f"'device:' says it), not {name!r}", ("profile",))
        source = self.mapping(top.get("source", {}), ("source",), "source")
        if source is not None:
            self.keys(source, SOURCE_KEYS, ("source",), "source")
            for k in ("document", "version"):
                if k not in source:
                    self.err("profile-source", f"source has no '{k}': name the vendor document and its version the "
                             "profile was written from", ("source",))
                else:
                    self.text(source[k], ("source", k), f"source {k}")
        link = self.choice(top.get("link", "can"), CAN_LINKS, ("link",), "link")
        params = self.parameters(top.get("parameters") or {})
        messages = self.mapping(top.get("messages", {}), ("messages",), "messages") or {}
        out_messages = []
        for mname, body in messages.items():
            got = self.message(str(mname), body, params, link)
            if got is not None:
                out_messages.append(got)
        device = {m["name"] for m in out_messages if m["from"] == "device"}
        for m in out_messages:
            if m.get("reply") and m["reply"] not in device:
                self.err("profile-reply", f"{m['name']} replies with '{m['reply']}', which is not a message the "
                         f"device sends{did_you_mean(m['reply'], device)}", ("messages", m["name"], "reply"))
        notes = top.get("notes") or []
        if not isinstance(notes, list) or not all(isinstance(n, str) for n in notes):
            self.err("profile-type", "notes must be a list of sentences", ("notes",))
        out = {
            "name": name, "format": FORMAT, "vendor": top.get("vendor", ""), "product": top.get("product", ""),
            "source": source or {}, "link": link, "parameters": params, "messages": out_messages, "notes": notes,
        }
        for key in ("enable", "safe_stop"):
            if key in top:
                out[key] = self.action(key, top[key], out_messages)
        if "ros2_control" in top:
            out["ros2_control"] = check_ros2_control(self, top["ros2_control"], params, out_messages)
        return out

    def action(self, key: str, data: Any, messages: list[dict[str, Any]]) -> dict[str, Any] | None:
        """`enable:` / `safe_stop:`: {message: a host message, values: {field: number or value name}}, every field
        of the message that is not a constant given."""
        body = self.mapping(data, (key,), key)
        if body is None:
            return None
        self.keys(body, ACTION_KEYS, (key,), key)
        host = {m["name"]: m for m in messages if m["from"] == "host"}
        name = body.get("message")
        if name not in host:
            self.err("profile-action", f"{key} sends '{name}', which is not a message the host sends"
                     f"{did_you_mean(str(name), host)}", (key, "message") if "message" in body else (key,))
            return None
        values = self.mapping(body.get("values", {}), (key, "values"), f"{key} values") or {}
        fields = {f["name"]: f for f in host[name].get("fields") or () if f.get("encoding") != "const"}
        for fname, value in values.items():
            where = (key, "values", fname)
            if fname not in fields:
                self.err("profile-action", f"'{name}' has no field '{fname}'{did_you_mean(str(fname), fields)}",
                         where, key=True)
            elif isinstance(value, str):
                names = [n for _, n in fields[fname].get("choices") or ()]
                if value not in names:
                    self.err("profile-action", f"{fname} has no value named {value!r}{did_you_mean(value, names)}",
                             where)
            else:
                self.number(value, where, f"{key} value {fname}")
        missing = [f for f in fields if f not in values]
        if missing:
            self.err("profile-action", f"{key}: give '{name}' the value of {', '.join(missing)} under 'values:'",
                     (key,))
            return None
        states: dict[str, set[str]] = {}  # every state field the device sends -> its value names
        for m in messages:
            for f in m.get("fields") or () if m["from"] == "device" else ():
                if f.get("role") == "state":
                    states.setdefault(f["name"], set()).update(n for _, n in f.get("choices") or ())
        state = self.mapping(body.get("state", {}), (key, "state"), f"{key} state") or {}
        for fname, value in state.items():
            if fname not in states:
                self.err("profile-action", f"{key} state: '{fname}' is not a state field of a device message"
                         f"{did_you_mean(str(fname), states)}", (key, "state", fname), key=True)
            elif value not in states[fname]:
                self.err("profile-action", f"{key} state: {fname} has no value named {value!r}"
                         f"{did_you_mean(str(value), states[fname])}", (key, "state", fname))
        return {"message": name, "values": dict(values), "state": dict(state)}

    def parameters(self, data: Any) -> dict[str, dict[str, Any]]:
        out: dict[str, dict[str, Any]] = {}
        block = self.mapping(data, ("parameters",), "parameters") or {}
        for pname, body in block.items():
            path: tuple[str | int, ...] = ("parameters", pname)
            if not _NAME.match(str(pname)):
                self.err("profile-name", f"parameter name {pname!r} must be a lower-case identifier", path, key=True)
            body = self.mapping(body, path, f"parameter {pname}")
            if body is None:
                continue
            self.keys(body, PARAM_KEYS, path, f"parameter {pname}")
            p: dict[str, Any] = {}
            for k in ("default", "min", "max"):
                if body.get(k) is not None and self.number(body[k], (*path, k), f"{pname} {k}") is not None:
                    p[k] = body[k]
            if "unit" in body:
                p["unit"] = body["unit"]
            low, high, default = p.get("min"), p.get("max"), p.get("default")
            if default is not None and ((low is not None and default < low) or (high is not None and default > high)):
                self.err("profile-range", f"{pname}'s default {default} is outside [{low}, {high}]", (*path, "default"))
            out[str(pname)] = p
        return out

    def message(self, name: str, data: Any, params: dict[str, dict[str, Any]], link: str) -> dict[str, Any] | None:
        path: tuple[str | int, ...] = ("messages", name)
        if not _NAME.match(name):
            self.err("profile-name", f"message name {name!r} must be a lower-case identifier", path, key=True)
        body = self.mapping(data, path, f"message {name}")
        if body is None:
            return None
        self.keys(body, MESSAGE_KEYS, path, f"message {name}")
        sender = self.choice(body.get("from"), ("host", "device"), (*path, "from"), f"{name}: from")
        fd = body.get("fd", LINKS[link].data_phase)
        if fd is True and not LINKS[link].data_phase:
            self.err("profile-fd", f"{name} is a CAN FD frame on a profile whose link is 'can'; say 'link: can-fd'",
                     (*path, "fd"))
        sizes = CAN_FD_SIZES if fd else tuple(range(9))
        size = body.get("size")
        if size not in sizes or type(size) is not int:
            self.err("profile-size", f"{name}: size must be one of {', '.join(map(str, sizes))} bytes "
                     f"({'a CAN FD' if fd else 'a classical CAN'} frame), not {size!r}", (*path, "size"))
            size = None
        extended = body.get("extended", False)
        if extended not in (True, False, "auto"):
            self.err("profile-value", f"{name}: extended must be true, false or auto (extended when the identifier "
                     "exceeds 11 bits, as moteus does)", (*path, "extended"))
            extended = False
        fields_in = self.mapping(body.get("fields", {}), (*path, "fields"), f"{name}: fields") or {}
        widths: dict[str, tuple[str, int]] = {}
        for pname, p in params.items():
            if p.get("max") is not None and p.get("min", 0) >= 0 and float(p["max"]).is_integer():
                widths[pname] = ("param", max(int(p["max"]).bit_length(), 1))
        for fname, fbody in fields_in.items():
            if isinstance(fbody, dict) and "start_bit" not in fbody and type(fbody.get("bits")) is int:
                widths[str(fname)] = ("field", fbody["bits"])
        parts: list[dict[str, Any]] = []
        in_id: set[str] = set()
        if "id" not in body:
            self.err("profile-missing", f"{name} has no 'id' (its identifier rule)", path, key=True)
        else:
            try:
                terms = parse_id_rule(body["id"], widths, 11 if extended is False else 29)
                parts = [t.plain() for t in terms]
                in_id = {str(t.value) for t in terms if t.kind == "field"}
            except IdRuleError as exc:
                self.err("profile-id", f"{name}: {exc}", (*path, "id"))
        out: dict[str, Any] = {"name": name, "from": sender, "id": {"extended": extended, "parts": parts},
                               "size": size or 0, "fd": bool(fd)}
        if "pad" in body and self.integer(body["pad"], (*path, "pad"), f"{name}: pad", 0, 255) is not None:
            out["pad"] = body["pad"]
        if body.get("remote"):
            if sender != "host" or fields_in or "data" in body:
                self.err("profile-remote", f"{name}: a remote (RTR) request is sent by the host and carries no data",
                         (*path, "remote"))
            out["remote"] = True
        if "data" in body:
            hexdata = str(body["data"]).replace(" ", "")
            if not re.fullmatch(r"([0-9A-Fa-f]{2})*", hexdata) or (size is not None and len(hexdata) != 2 * size):
                self.err("profile-data", f"{name}: data must be {size} bytes in hex ('FF FF ... FC')", (*path, "data"))
            elif fields_in:
                self.err("profile-data", f"{name}: a fixed frame (data:) has no fields", (*path, "fields"))
            out["data"] = hexdata.upper()
        out["fields"] = self.fields(name, fields_in, params, size, in_id)
        self.timing(name, body, sender, params, out)
        return out

    def timing(self, name: str, body: dict[str, Any], sender: str | None, params: dict[str, dict[str, Any]],
               out: dict[str, Any]) -> None:
        path: tuple[str | int, ...] = ("messages", name)
        if "cyclic" in body:
            if sender != "device":
                self.err("profile-cyclic", f"{name}: only the device's own messages are cyclic", (*path, "cyclic"))
            elif body["cyclic"] not in params:
                self.err("profile-cyclic", f"{name}: cyclic names the parameter that sets its period in ms, and "
                         f"{body['cyclic']!r} is not one{did_you_mean(str(body['cyclic']), params)}", (*path, "cyclic"))
            else:
                out["cyclic"] = body["cyclic"]
        reply = body.get("reply")
        if reply is None or reply == "none":
            return
        rpath = (*path, "reply")
        if sender != "host":
            self.err("profile-reply", f"{name}: a reply answers a host's command; the device's messages have none",
                     rpath)
            return
        r = self.mapping(reply, rpath, f"{name}: reply")
        if r is None:
            return
        self.keys(r, REPLY_KEYS, rpath, f"{name}'s reply")
        out["reply"] = r.get("message")
        delay = r.get("delay_us")
        if (not isinstance(delay, list) or len(delay) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in delay)
                or not 0 <= delay[0] <= delay[1]):
            self.err("profile-delay", f"{name}: give the reply's delay as delay_us: [min, max] (µs after the command "
                     "ends on the bus)", (*rpath, "delay_us") if "delay_us" in r else rpath)
            return
        basis = self.choice(r.get("basis"), ("published", "assumed"), (*rpath, "basis"), f"{name}: reply basis")
        if basis is not None and not r.get("note"):
            self.err("profile-delay", f"{name}: say where the delay comes from in 'note' (the document's section, or "
                     "why the assumption holds)", rpath)
        out["reply_delay_us"] = [delay[0], delay[1]]
        out["delay_basis"] = f"{basis}: {r.get('note', '')}"

    def fields(self, mname: str, data: dict[str, Any], params: dict[str, dict[str, Any]], size: int | None,
               in_id: set[str]) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        used: dict[tuple[int, int], str] = {}  # (byte, bit) -> field
        for fname, body in data.items():
            path: tuple[str | int, ...] = ("messages", mname, "fields", fname)
            fname = str(fname)
            if not _NAME.match(fname):
                self.err("profile-name", f"field name {fname!r} must be a lower-case identifier", path, key=True)
            body = self.mapping(body, path, f"field {fname}")
            if body is None:
                continue
            self.keys(body, FIELD_KEYS, path, f"field {fname}")
            f = self.field(fname, body, params, path)
            if f is None:
                continue
            if fname in in_id:
                f["location"] = "id"
                if "byte_order" in body:
                    self.err("profile-field", f"{fname} sits in the identifier; it has no byte order", path)
            elif "start_bit" not in body:
                self.err("profile-field", f"{fname} has no start_bit, and the identifier rule does not name it",
                         path, key=True)
                continue
            else:
                f["location"] = "payload"
                start = self.integer(body["start_bit"], (*path, "start_bit"), f"{fname}: start_bit", 0, 511)
                if start is None:
                    continue
                f["start_bit"] = start
                ops = byte_ops(start, f["bits"], f.get("byte_order") == "big")
                if size is not None and max(op.index for op in ops) >= size:
                    self.err("profile-field", f"{fname} (bits from {start}, {f['bits']} wide) runs past the "
                             f"{size}-byte frame", (*path, "start_bit"))
                    continue
                for op in ops:
                    for bit in range(8):
                        if op.mask >> bit & 1:
                            other = used.setdefault((op.index, bit), fname)
                            if other != fname:
                                self.err("profile-overlap", f"{fname} and {other} share byte {op.index} bit {bit}",
                                         (*path, "start_bit"))
                                break
            out.append(f)
        return out

    def field(self, fname: str, body: dict[str, Any], params: dict[str, dict[str, Any]],
              path: tuple[str | int, ...]) -> dict[str, Any] | None:
        bits = self.integer(body.get("bits"), (*path, "bits"), f"{fname}: bits", 1, 64)
        if bits is None:
            return None
        f: dict[str, Any] = {"name": fname, "bits": bits}
        order = self.choice(body.get("byte_order", "little_endian"), ("little_endian", "big_endian"),
                            (*path, "byte_order"), f"{fname}: byte_order")
        f["byte_order"] = "big" if order == "big_endian" else "little"
        kind = self.choice(body.get("type", "unsigned"), ("unsigned", "signed", "float"), (*path, "type"),
                           f"{fname}: type")
        f["type"] = kind or "unsigned"
        if kind == "float" and bits not in (32, 64):
            self.err("profile-field", f"{fname}: a float is 32 or 64 bits, not {bits}", (*path, "bits"))
        encoding = self.choice(body.get("encoding", "linear"), ("linear", "span"), (*path, "encoding"),
                               f"{fname}: encoding")
        f["encoding"] = encoding or "linear"
        for k in ("scale", "offset"):
            if k in body and self.number(body[k], (*path, k), f"{fname}: {k}") is not None:
                f[k] = float(body[k])
        if f.get("scale") == 0:
            self.err("profile-field", f"{fname}: scale 0 makes every value the same", (*path, "scale"))
        if "range" in body:
            f["range"] = self.range(fname, body["range"], params, (*path, "range"))
        if encoding == "span":
            if kind != "unsigned":
                self.err("profile-field", f"{fname}: a span field's raw value is unsigned (MIT packing maps [lo, hi] "
                         "onto 0..2^bits-1)", (*path, "type"))
            if "range" not in body:
                self.err("profile-field", f"{fname}: a span field needs range: [lo, hi]", path, key=True)
            if "scale" in body or "offset" in body:
                self.err("profile-field", f"{fname}: a span field's range sets its scale; drop scale/offset", path)
        if "value" in body:
            value = body["value"]
            if isinstance(value, str) and value in params:
                f["value"] = {"param": value}
            elif type(value) is int and 0 <= value < 1 << bits:
                f["value"] = value
            else:
                self.err("profile-field", f"{fname}: value must be a whole number of {bits} bits or a parameter's "
                         f"name, not {value!r}", (*path, "value"))
            f["encoding"] = "const"
        unit = body.get("unit", "1")
        if unit not in SI_UNITS:
            hint = did_you_mean(str(unit), SI_UNITS)
            self.err("profile-unit", f"{fname}: unit {unit!r} is not one netcfg converts to SI{hint}; known: "
                     f"{', '.join(SI_UNITS)}", (*path, "unit"))
        f["unit"] = unit
        f["role"] = self.choice(body.get("role", "value"), ("value", "error", "state"), (*path, "role"),
                                f"{fname}: role") or "value"
        for k in ("flags", "choices"):
            if k in body:
                table = self.mapping(body[k], (*path, k), f"{fname}: {k}") or {}
                limit = bits if k == "flags" else 1 << bits
                rows = []
                for raw, label in table.items():
                    try:
                        number = int(str(raw), 0)
                    except ValueError:
                        number = -1
                    if not 0 <= number < limit or not isinstance(label, str):
                        what = "a bit number" if k == "flags" else "a raw value"
                        self.err("profile-field", f"{fname}: {k} maps {what} below {limit} to a name, not "
                                 f"{raw!r}: {label!r}", (*path, k, raw))
                        continue
                    rows.append([number, label])
                f[k] = rows
        if "error_values" in body:
            values = body["error_values"]
            if not isinstance(values, list) or not all(type(v) is int for v in values):
                self.err("profile-field", f"{fname}: error_values is a list of raw values", (*path, "error_values"))
            else:
                f["error_values"] = values
        return f

    def range(self, fname: str, value: Any, params: dict[str, dict[str, Any]],
              path: tuple[str | int, ...]) -> list[Any] | None:
        if not isinstance(value, list) or len(value) != 2:
            self.err("profile-field", f"{fname}: range is [lo, hi]", path)
            return None
        out: list[Any] = []
        for i, bound in enumerate(value):
            if isinstance(bound, str):
                negate, name = bound.startswith("-"), bound.removeprefix("-").strip()
                if name not in params:
                    self.err("profile-field", f"{fname}: range bound {bound!r} names no parameter"
                             f"{did_you_mean(name, params)}", (*path, i))
                    return None
                out.append({"param": name, "negate": negate})
            elif self.number(bound, (*path, i), f"{fname}: range bound") is not None:
                out.append(float(bound))
            else:
                return None
        return out
