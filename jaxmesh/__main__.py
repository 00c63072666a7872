"""``python -m jaxmesh``: the same as the ``jaxmesh`` command."""

from .cli import command

command()
