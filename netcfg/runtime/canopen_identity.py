"""What a CANopen node's identity object (0x1018) must hold: from runtime.json, or from a generated EDS/DCF."""

from __future__ import annotations

import configparser
from dataclasses import dataclass
from pathlib import Path

from netcfg.runtime import Node, RuntimeConfig
from netcfg.runtime.canopen_network import canopen_bus, canopen_slaves

__all__ = ["Identity", "identities_from_dir", "identity_from_eds", "identity_from_runtime"]

# --- identities ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Identity:
    """What a node's 0x1018 must hold. None: not checked (an EDS with product number 0 gives no product code)."""

    vendor_id: int | None
    product_code: int | None = None
    revision: int | None = None
    source: str = ""


def _eds_int(text: str) -> int:
    text = text.strip()
    return int(text, 16) if text.lower().startswith("0x") else int(text, 10)


def identity_from_eds(path: str | Path) -> Identity:
    """The identity an EDS/DCF's [DeviceInfo] declares (VendorNumber, ProductNumber, RevisionNumber)."""
    parser = configparser.ConfigParser(interpolation=None, strict=False)
    parser.optionxform = str  # type: ignore[assignment,method-assign]  # EDS keys are case-sensitive
    with open(path, encoding="utf-8", errors="replace") as fh:
        parser.read_file(fh)
    info = parser["DeviceInfo"]
    product = _eds_int(info["ProductNumber"]) if info.get("ProductNumber", "").strip() else 0
    revision = _eds_int(info["RevisionNumber"]) if info.get("RevisionNumber", "").strip() else 0
    return Identity(_eds_int(info["VendorNumber"]), product or None, revision or None, str(path))


def identity_from_runtime(cfg: RuntimeConfig, node: Node) -> Identity | None:
    """The identity runtime.json states for a node (node.identity); None when it states none or knows no value."""
    ident = node.identity
    if ident is None or (ident.vendor_id is None and ident.product_code is None):
        return None
    return Identity(ident.vendor_id, ident.product_code, ident.revision, cfg.source)


def identities_from_dir(cfg: RuntimeConfig, directory: str | Path, bus_name: str | None = None) -> dict[str, Identity]:
    """Expected identities of a bus's slaves: runtime.json's node.identity where it has one, else (a runtime.json
    written before that key) `<directory>/<node>.dcf` (else `.eds`), as netcfg writes them to
    generated/<system>/canopen/. Nodes without either are left out (not checked)."""
    found = {}
    for node in canopen_slaves(cfg, canopen_bus(cfg, bus_name)):
        stated = identity_from_runtime(cfg, node)
        if stated is not None:
            found[node.name] = stated
            continue
        for suffix in (".dcf", ".eds"):
            path = Path(directory) / f"{node.name}{suffix}"
            if path.is_file():
                found[node.name] = identity_from_eds(path)
                break
    return found
