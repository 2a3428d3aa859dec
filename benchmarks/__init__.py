"""Benchmarks of fourbar_ros: run time against error, numerical stress, peers. Entry: ``python -m benchmarks.run``.

Not part of the installed package. The error of every method is measured against :mod:`benchmarks.reference`,
an independent 50-digit evaluation (mpmath) derived from the loop-closure equations, not from the core's code.
"""
