"""``python -m jaxmesh.cli``: the same as the ``jaxmesh`` command."""

from . import command

command()
