"""``python -m jaxmesh.cli``: the same as the ``jaxmesh`` command."""

import sys

from . import main

sys.exit(main())
