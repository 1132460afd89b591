"""`check`'s tables a person reads: messages by identifier, the order of priority on a CAN bus."""

from __future__ import annotations

from pathlib import Path

import yaml
from conftest import cli


def test_messages_are_listed_by_identifier(tmp_path: Path) -> None:
    """Written 0x300, 0x100, 0x200: listed 0x100, 0x200, 0x300 (lower identifier, higher priority, ISO 11898-1)."""
    spec = {
        "system": "order",
        "buses": [{"name": "can0", "protocol": "can", "bitrate": "500k"}],
        "nodes": [{"name": "a", "buses": ["can0"]}, {"name": "b", "buses": ["can0"]}],
        "messages": [
            {"name": name, "id": ident, "producer": "a", "consumers": ["b"], "period": "10 ms", "size": 2}
            for name, ident in (("late", 0x300), ("first", 0x100), ("middle", 0x200))
        ],
    }
    path = tmp_path / "order.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    proc = cli("check", str(path))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    listed = [line.split()[0] for line in proc.stdout.splitlines() if line.strip().startswith(("late", "first", "mid"))]
    assert listed == ["first", "middle", "late"]
