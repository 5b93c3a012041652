"""``python -m mbctl.cli``: the same as the ``mbctl`` console script."""

from mbctl.cli import main

main()
