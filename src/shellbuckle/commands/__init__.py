"""The sub-commands of ``shellbuckle``, one module each.

Each module here defines ``register(subparsers)``, which adds its sub-command to the
``shellbuckle`` parser and sets its ``func`` with ``set_defaults``; :mod:`shellbuckle.cli`
finds them at start-up, so adding a command never means editing a shared list. Modules whose
name starts with ``_`` are not commands: :mod:`._options` declares the options several commands
share (the shell, the protocol, threads, steps) with the library's defaults, :mod:`._output`
prints what a run-making command reports. Commands report bad input by raising ``ValueError``
(exit code 2, the message on stderr; :func:`shellbuckle.cli.main`).
"""
