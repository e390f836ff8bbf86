"""``python -m moments_ref`` is the ``moments-ref`` command."""

from .cli import main

raise SystemExit(main())
