from course.app.cli import main

raise SystemExit(main())
