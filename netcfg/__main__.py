from netcfg.commands import command

raise SystemExit(command())
