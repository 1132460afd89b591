from netcfg.cli import main

raise SystemExit(main())
