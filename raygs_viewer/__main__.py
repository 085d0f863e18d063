from raygs_viewer.cli.main import main

raise SystemExit(main())
