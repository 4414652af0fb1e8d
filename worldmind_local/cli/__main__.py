from worldmind_local.cli import main

raise SystemExit(main())
