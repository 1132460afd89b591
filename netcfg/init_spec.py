"""The starting specs of `netcfg init` (netcfg.commands.init): commented, and accepted by `netcfg check`.

Without --from: a small CAN system with every key explained (templates/init_spec.yaml.j2). With --from SYSTEM:
one of the example specs written from our customers' papers (shipped in the package as netcfg.examples), whose
comments say where each number comes from. With --from dbc FILE: the DBC importer's spec.
"""

from __future__ import annotations

import re
from pathlib import Path

# --from names -> example spec; `ntua` is the hopping robot, the richer of the two NTUA systems
EXAMPLES = {
    "allex2": "allex2",
    "cambada": "cambada",
    "ntua": "ntua_sahr",
    "ntua_sahr": "ntua_sahr",
    "ntua_treadmill": "ntua_treadmill",
}
SOURCES = (*EXAMPLES, "dbc")


def example_text(name: str) -> str:
    from importlib import resources  # here: every command's argument parser imports this module for SOURCES

    return resources.files("netcfg.examples").joinpath(f"{EXAMPLES[name]}.yaml").read_text("utf-8")


def _safe_system_name(name: str) -> str:
    """A system name `check` accepts, from a file name that may be a C keyword or too long (`new.yaml`, `int.yml`)."""
    from netcfg.spec.schema import check_name

    for candidate in (name, f"{name[:56]}_system"):
        try:
            return check_name(candidate)
        except ValueError:
            continue
    return "my_system"


def starting_spec(source: str | None, output: Path | None) -> str:
    """The text of the starting spec (not for dbc, which goes through the importer)."""
    if source is None:
        from netcfg.templating import render

        stem = output.stem if output is not None else "my_system"
        system = re.sub(r"[^A-Za-z0-9_]", "_", stem) or "my_system"
        if system[0].isdigit():
            system = f"s_{system}"
        system = _safe_system_name(system)
        name = output.name if output is not None else "spec.yaml"
        return render("init_spec.yaml.j2", system=system, file_name=name).decode("utf-8")
    header = (
        f"# Started from netcfg's '{EXAMPLES[source]}' example by `netcfg init --from {source}`: edit it for your "
        "system,\n# then `netcfg check` it. `netcfg schema` lists every key.\n"
    )
    return header + example_text(source)
