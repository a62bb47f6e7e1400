"""Run the lessons' notebooks headless, as the suite does: ``python lessons/run.py [--solutions] [NOTEBOOK ...]``.

Without ``--solutions`` each notebook runs as it is (a student's copy: the check cell
passes once the exercise is done). With ``--solutions`` the source of every cell tagged
``exercise`` is replaced by the text of ``solutions/<notebook's name>.py`` before the run,
so the checks must pass. The notebook file is never written. Exit status 1 when a
notebook fails, with the failing cell's error.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
NOTEBOOKS = sorted(HERE.glob("[0-9][0-9]_*.ipynb"))


def load(path: Path, solutions: bool = False):
    """The notebook at ``path``, with its exercise cells replaced by the solution's text when ``solutions``."""
    import nbformat

    nb = nbformat.read(path, as_version=4)
    if solutions:
        solution = (path.parent / "solutions" / (path.stem + ".py")).read_text()
        cells = [c for c in nb.cells if "exercise" in c.get("metadata", {}).get("tags", [])]
        if not cells:
            raise ValueError(f"{path.name}: no cell is tagged 'exercise' to put the solution in")
        for c in cells:
            c.source = solution
    return nb


def run(path: Path, solutions: bool = False, timeout: int = 600):
    """Execute the notebook in a fresh kernel, in the lessons' folder; return the executed notebook.

    Raises nbclient's CellExecutionError (its text holds the failing cell's traceback) when a cell fails.
    """
    from nbclient import NotebookClient

    nb = load(path, solutions)
    NotebookClient(nb, timeout=timeout, kernel_name="python3",
                   resources={"metadata": {"path": str(path.parent)}}).execute()
    return nb


def run_both(path: Path, timeout: int = 600):
    """The notebook as a student gets it, then with the solutions, in one kernel: (the error text the
    first failing cell stops with, or None if none fails; the notebook executed with the solutions).

    The cells before the first exercise cell run once; the notebook as given runs on to its first
    failing cell (or to the end), then the run goes back to the first exercise cell and runs from there
    to the end with the solutions in the exercise cells, as :func:`run` with ``solutions`` would (the
    cells before it are the same in both).
    Raises CellExecutionError when a cell fails with the solutions.
    """
    from nbclient import NotebookClient
    from nbclient.exceptions import CellExecutionError

    given, solved = load(path), load(path, solutions=True)
    first = next(i for i, c in enumerate(given.cells) if "exercise" in c.get("metadata", {}).get("tags", []))
    client = NotebookClient(given, timeout=timeout, kernel_name="python3",
                            resources={"metadata": {"path": str(path.parent)}})
    failure = None
    with client.setup_kernel():
        for i, cell in enumerate(given.cells):
            if cell.cell_type != "code":
                continue
            try:
                client.execute_cell(cell, i)
            except CellExecutionError as e:
                if i < first:
                    raise                            # before any exercise: the lesson itself is broken
                failure = str(e)
                break
        for i in range(first, len(solved.cells)):
            if solved.cells[i].cell_type == "code":
                client.execute_cell(solved.cells[i], i)
    for i in range(first):                           # the cells both runs share, as they ran
        solved.cells[i] = given.cells[i]
    return failure, solved


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--solutions", action="store_true", help="run with the solutions in the exercise cells")
    parser.add_argument("notebooks", nargs="*", type=Path, help="default: every lesson")
    args = parser.parse_args(argv)
    failed = 0
    for path in args.notebooks or NOTEBOOKS:
        start = time.perf_counter()
        try:
            run(path.resolve(), args.solutions)
            print(f"{path.name}: passed ({time.perf_counter() - start:.1f} s)")
        except Exception as e:                       # a failing cell: show its error and go on
            failed += 1
            print(f"{path.name}: failed ({time.perf_counter() - start:.1f} s)\n{e}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
