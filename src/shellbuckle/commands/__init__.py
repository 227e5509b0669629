"""Sub-commands that live in their own module.

Each module here defines ``register(subparsers)``, which adds one sub-command to the
``shellbuckle`` parser and sets its ``func`` with ``set_defaults``; ``shellbuckle.cli`` finds them
at start-up, so adding a command never means editing a shared list. Commands report bad input by
raising ``ValueError`` (exit code 2, the message on stderr), as in ``shellbuckle.cli``.
"""
