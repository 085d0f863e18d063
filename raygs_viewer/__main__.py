from raygs_viewer.cli import main

raise SystemExit(main())
