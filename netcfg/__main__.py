from netcfg.cli import command

raise SystemExit(command())
