"""The application layer: the ``hqp`` command line and what it runs.

One module per subcommand (:mod:`~hqp.app.compare`, :mod:`~hqp.app.run`,
:mod:`~hqp.app.behaviors`, :mod:`~hqp.app.bench`), :mod:`~hqp.app.record` (re-records the
benchmark's control problems), :mod:`~hqp.app.cli` (the parser and ``main``). The only layer
of ``hqp/`` that imports :mod:`comparisons`.
"""
