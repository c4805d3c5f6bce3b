"""`python -m portal_harness` is the same as the `portal-harness` command."""

from portal_harness.cli import main

raise SystemExit(main())
