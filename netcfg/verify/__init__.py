"""netcfg.verify: a recorded CAN log (or any stream of frames) held against the configuration and its analysis.

    from netcfg.verify import verify_log
    report = verify_log(cfg, Path("robot.log"))          # the JSON document of `netcfg verify --format json`

A master or the simulator that has the frames already feeds them itself:

    checker = Checker(cfg)
    checker.feed_messages(received)                      # python-can Messages, in time order, as many as needed
    report = checker.finish()

`netcfg verify`, `netcfg simulate --log` and a live master all use this one checker, so they agree on what a
violation is (see netcfg.verify.checker for the list).
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from netcfg.verify.api import check_frames, verify_log
    from netcfg.verify.checker import Checker, VerifyError
    from netcfg.verify.frames import Batch, ChannelTable
    from netcfg.verify.logs import LogError

__all__ = ["Batch", "ChannelTable", "Checker", "LogError", "VerifyError", "check_frames", "verify_log"]

# names -> their modules, imported on first use: the command line registers `verify` without loading numpy
_HOME = {
    "check_frames": "api",
    "verify_log": "api",
    "Checker": "checker",
    "VerifyError": "checker",
    "Batch": "frames",
    "ChannelTable": "frames",
    "LogError": "logs",
}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module 'netcfg.verify' has no attribute {name!r}")
    return getattr(import_module(f"netcfg.verify.{_HOME[name]}"), name)
