"""`netcfg build`: check, then emit every artifact into the output folder, atomically.

Files are written into a temporary folder next to the output and swapped in only when everything succeeded,
so an interrupted or failed build leaves the previous output as it was. netcfg.outputs decides whether the
folder may be replaced at all (only an absent or empty one, or one carrying netcfg's manifest).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

from netcfg import protocols
from netcfg.check import analyse_spec
from netcfg.emit import Background, Files, emit_all
from netcfg.emit.dbc import unsaid
from netcfg.inputs import read_input_bytes
from netcfg.outputs import check_output_folder, write_tree


def build(spec: Path, out: Path | None, worker: Background | None = None) -> tuple[dict[str, Any], Path | None, Files]:
    """-> (check report, output folder or None when the spec was refused, files written).

    worker: the emitters' background worker, best started before this module is imported (Background.start());
    it is closed on return.

    report["kept"] lists the files of the user's that were found in netcfg's output folder and kept there;
    report["notes"] what of the spec a written file cannot say (a DBC: netcfg.emit.dbc.unsaid; the ros2_control
    description: the joints no published plugin drives, netcfg.emit.ros2_control.unsaid).
    Raises OutputError (an OSError) when the output folder is one netcfg must not replace."""
    if worker is None:
        worker = Background.start()  # it imports what the report needs while the spec is analysed here
    try:
        if out is not None:
            check_output_folder(out, [spec])  # refuse before the analysis, which can take a while
        model, report = analyse_spec(spec)
        if model is None or not report["ok"]:
            return report, None, {}
        files = emit_all(model, report, worker)
        report["notes"] = [f"{name}: it cannot say {u.what}" for name, lost in unsaid(model).items() for u in lost]
        from netcfg.emit import ros2_control  # after emit_all, which has imported it

        report["notes"] += ros2_control.unsaid(model)
        report["notes"] += [note for bus in model.buses.values() for note in protocols.of(bus).build_notes(bus)]
    finally:
        worker.close()
    target = out if out is not None else Path("generated") / model.system
    spec_sha256 = hashlib.sha256(read_input_bytes(spec, "spec")).hexdigest()
    report["kept"] = write_tree(target, files, spec_sha256, [spec])
    return report, target, files
