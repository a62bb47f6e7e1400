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
    """The notebook as a student gets it, and with the solutions, in one kernel: (the error text of each
    exercise's failing cell as given, in order; the notebook executed with the solutions).

    The cells run in order as given. When one fails, the first exercise cell before it still as given
    gets the solution's text, and the run goes back to that exercise cell; so each exercise's skeleton
    is met with the exercises before it solved, as a student meets it, and the run ends with every
    exercise that failed solved (the cells before the first exercise run once). Raises
    CellExecutionError when a cell fails with every exercise before it solved.
    """
    from nbclient import NotebookClient
    from nbclient.exceptions import CellExecutionError

    nb = load(path)
    solution = (path.parent / "solutions" / (path.stem + ".py")).read_text()
    exercises = [i for i, c in enumerate(nb.cells) if "exercise" in c.get("metadata", {}).get("tags", [])]
    client = NotebookClient(nb, timeout=timeout, kernel_name="python3",
                            resources={"metadata": {"path": str(path.parent)}})
    failures, solved = [], set()
    with client.setup_kernel():
        i = 0
        while i < len(nb.cells):
            if nb.cells[i].cell_type == "code":
                try:
                    client.execute_cell(nb.cells[i], i)
                except CellExecutionError as e:
                    given = [j for j in exercises if j <= i and j not in solved]
                    if not given:
                        raise                        # it fails with the solutions: the lesson is broken
                    failures.append(str(e))
                    i = given[0]
                    nb.cells[i].source = solution
                    solved.add(i)
                    continue
            i += 1
    return failures, nb


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
