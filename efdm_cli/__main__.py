"""``python -m efdm_cli``: the ``efdm`` command line."""

from __future__ import annotations

from efdm_cli import main

raise SystemExit(main())
