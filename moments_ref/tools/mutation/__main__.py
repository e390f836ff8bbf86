"""``python -m moments_ref.tools.mutation``: see :mod:`moments_ref.tools.mutation`."""

from . import main

raise SystemExit(main())
