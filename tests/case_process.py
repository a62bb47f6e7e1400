"""Several crash cases in one fresh Python: :func:`run_cases`, for tests whose cases each need a process of
their own only should one crash (a segmentation fault must fail the test, not end pytest).

One process for all of them instead of one a case: each process costs an interpreter, numba and softpipe
imported, and softpipe's kernels loaded from the caches again. Should a case end its process, that case
gets the process's return code and the cases after it run in the next process: each case's outcome is
what it would be in a process of its own.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: The child of :func:`run_cases`: each case named on its command line run as ``python -c SOURCE ARGS...``
#: would run it (in ``__main__``, its argv), between markers on both streams; a case's exit status
#: (SystemExit, or 1 for an exception, whose traceback it prints) follows its end marker.
_CASES_CHILD = """
import __main__, json, sys, traceback
cases = json.loads(sys.stdin.read())
for name in sys.argv[1:]:
    source, args = cases[name]
    for stream in (sys.stdout, sys.stderr):
        print("\\x1ecase " + name, file=stream, flush=True)
    sys.argv = ["-c", *args]
    try:
        exec(compile(source, "<string>", "exec"), __main__.__dict__)
        code = 0
    except SystemExit as stop:
        code = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
    except BaseException:
        traceback.print_exc()
        code = 1
    sys.stderr.flush()
    print("\\x1fend " + str(code), flush=True)
"""


def run_cases(cases: dict, last=(), timeout: float = 600) -> dict:
    """``{name: (code, args)}`` run in fresh Pythons, one process for all of them while none crashes:
    ``{name: CompletedProcess}``, each with the case's own exit status and output. A case that ends its
    process (a signal, os._exit) gets the process's return code and what it printed; the cases after it
    run in the next process. One process instead of one a case: each costs an interpreter, numba and
    softpipe imported, and softpipe's kernels loaded from the caches again. A case named in ``last`` (one
    that changes what outlives it in the process: a module's object) is the last of its process."""
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    payload = json.dumps({name: [textwrap.dedent(code), list(args)] for name, (code, args) in cases.items()})
    results, left = {}, list(cases)
    while left:
        batch = left[:next((k + 1 for k, name in enumerate(left) if name in last), len(left))]
        done = subprocess.run([sys.executable, "-c", _CASES_CHILD, *batch], input=payload, env=env, cwd=ROOT,
                              capture_output=True, text=True, timeout=timeout)
        outs, errs = done.stdout.split("\x1ecase "), done.stderr.split("\x1ecase ")
        assert len(outs) > 1, f"the cases' process ended before its first case ({done.returncode}):\n{done.stderr}"
        for out, err in zip(outs[1:], errs[1:]):
            name, out = out.split("\n", 1)
            err = err.split("\n", 1)[1] if "\n" in err else ""
            out, end, code = out.rpartition("\x1fend ")
            if not end:                                  # the process ended inside this case
                out, code = code, str(done.returncode)
            results[name] = subprocess.CompletedProcess([name], int(code.strip()), out, err)
            left.remove(name)
    return results


class Cases:
    """The crash cases of one test file, for its module-scoped fixture: ``cases(name)`` is the
    CompletedProcess of case ``name``, all of them run (on the first call, by :func:`run_cases`) that the
    session's tests of this file read (``case_of(item)``: the name of the case a collected test reads, or
    None); a file's single test run alone runs its case only. ``last``: as :func:`run_cases`'s."""

    def __init__(self, request, cases: dict, case_of, last=()):
        here = Path(request.module.__file__)
        self.cases, self.results, self.last = cases, {}, last
        self.wanted = [name for name in dict.fromkeys(case_of(item) for item in request.session.items
                                                      if Path(item.path) == here) if name in cases]

    def __call__(self, name: str) -> subprocess.CompletedProcess:
        if not self.results:
            self.results.update(run_cases({c: self.cases[c] for c in self.wanted}, self.last))
        assert name in self.results, f"case {name!r} was not run: {self.wanted}"
        return self.results[name]
