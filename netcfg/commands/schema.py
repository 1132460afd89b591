"""`netcfg schema`: print the JSON Schema of the spec language (the pydantic models of netcfg.spec.schema)."""

from __future__ import annotations

import argparse

from netcfg import jsontext
from netcfg.commands.base import Subcommands

NAME = "schema"
BATCH = False


def add_parser(sub: Subcommands) -> None:
    sub.add_parser(NAME, help="print the JSON Schema of the spec language (for editors)")


def run(args: argparse.Namespace) -> int:
    from netcfg.spec.schema import Spec

    schema = Spec.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "netcfg spec"
    print(jsontext.dumps(schema, indent=2, sort_keys=True))
    return 0
