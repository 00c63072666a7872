"""``python -m jaxmesh``: the same as the ``jaxmesh`` command."""

import sys

from .cli import main

sys.exit(main())
