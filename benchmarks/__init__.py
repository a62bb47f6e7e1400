"""softpipe's benchmarks: the standard scenes (:mod:`benchmarks.scenes`) and the
timing harness (:mod:`benchmarks.run`, ``python -m benchmarks.run`` or ``make bench``).

Numbers, not pass/fail: nothing here is timed by ``make test``, which only runs
every scene once at a tiny size (``tests/test_benchmarks.py``) so that the
harness cannot rot. See ``benchmarks/README.md``.

This file imports nothing on purpose: ``python -m benchmarks.run`` must be able
to limit BLAS to one thread before numpy is imported.
"""
