"""The code behind ropecam's tools: one module per subcommand of `bench.py`, `evaluate.py`, `fuzz.py` and `soak.py`,
and the helpers they share (`cli`, `frames`, `timing`, `reference`).

A subcommand module exposes ``add_arguments(parser)`` and ``run(args) -> int``; the first line of its docstring is
the subcommand's one-line help. Nothing in ``ropecam`` imports this package, and pytest does not collect it: the
tools are scripts over ropecam's public API, tested end to end in ``tests/tools``.
"""
