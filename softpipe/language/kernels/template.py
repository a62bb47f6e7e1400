"""Reading the loop templates: a function out of a file of ``templates/``, specialised and filled in.

The fixed parts of the generated loops are real Python in ``templates/*.py``,
so a linter reads them as it reads any module; :mod:`.generate` takes a function
out of one with :func:`template_function` (or the expression a small function
returns, with :func:`template_expression`), and three rules make it the source
of the generated loop:

1. **Notes are left out**: a comment on a line of its own is for the template's
   reader; a comment after code is part of the generated code and stays.
2. **Constants decide**: an ``if`` whose test reads only compile-time constants
   (``SMOOTH``, ``DERIVATIVES``; ``shading`` for ``visible_loop_at_samples``)
   is replaced by the branch it takes, dedented; any other read of a constant
   becomes its value.
3. **Placeholders are filled**: a placeholder is a name in capitals. On a line
   of its own (``STORE_VARYINGS(i, v, out_varyings)``, the arguments saying
   what the generated lines read) it stands for statements, and is replaced
   by the generator's lines at its indentation, or by none; anywhere else
   (``Attributes(ATTRIBUTE_VALUES)``) it stands for text.

So the generated source is the template's text, character for character, but
where a rule says otherwise. A placeholder or constant the template does not
name is an error; one it names but is not given stays in the code as a name
in capitals (tests/test_kernel_templates.py checks that none does).
"""
from __future__ import annotations

import ast
import functools
import io
import re
import tokenize
from pathlib import Path
from typing import Any, List, Mapping, Sequence, Tuple, Union

__all__ = ["TEMPLATE_DIR", "template_function", "template_expression", "template_files"]

#: The folder of the templates (shipped as package data, hashed with softpipe's sources).
TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"

Fill = Mapping[str, Union[str, Sequence[str]]]


def template_files() -> List[Path]:
    """The template files: every file of ``templates/`` (Python's caches left out)."""
    return sorted(p for p in TEMPLATE_DIR.rglob("*") if p.is_file() and "__pycache__" not in p.parts)


@functools.lru_cache(maxsize=None)
def _template(name: str) -> Tuple[str, ast.Module]:
    """The text of ``templates/<name>.py`` and its syntax tree (read once per process)."""
    text = (TEMPLATE_DIR / f"{name}.py").read_text(encoding="utf-8")
    return text, ast.parse(text, filename=f"templates/{name}.py")


def _function_node(template: str, name: str) -> Tuple[str, ast.FunctionDef]:
    text, tree = _template(template)
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and node.name == name:
            return text, node
    raise KeyError(f"templates/{template}.py has no function {name!r}")


def template_function(template: str, name: str, constants: Mapping[str, Any] | None = None,
                      fill: Fill | None = None, rename: str | None = None) -> str:
    """The source of function ``name`` of ``templates/<template>.py`` (its decorators too), made concrete.

    Parameters
    ----------
    template : str
        The template file's name without ``.py`` (``"fragment"``).
    name : str
        The function to take.
    constants : mapping of str to a value
        Compile-time constants: the ``if`` statements that read only these are decided
        here, and other reads of them become their value (rule 2 of the module).
    fill : mapping of str to str or a sequence of str
        Placeholders: a sequence of lines for one standing on a line of its own, text
        for one inside a line (rule 3).
    rename : str, optional
        The name the generated function gets instead of ``name``.

    Returns
    -------
    str
        The function's source, each line ending in a newline.
    """
    source = _specialised(template, name, tuple(sorted((constants or {}).items())))
    source = _fill(source, dict(fill or {}), f"templates/{template}.py:{name}")
    if rename is not None:
        source, n = re.subn(rf"^([ ]*def ){re.escape(name)}\(", rf"\g<1>{rename}(", source, count=1, flags=re.M)
        assert n == 1, name
    return source


def template_expression(template: str, name: str, fill: Mapping[str, Any]) -> str:
    """The expression function ``name`` of ``templates/<template>.py`` returns, its placeholders filled.

    Such a function's body is its docstring and ``return <expression>`` on one line;
    its parameters name what the expression reads (placeholders among them), so a
    linter knows them. Each value of ``fill`` is written as ``str(value)``.
    """
    expression = _expression_text(template, name)
    return _replace_names(expression, {k: str(v) for k, v in fill.items()}, f"templates/{template}.py:{name}")


@functools.lru_cache(maxsize=None)
def _specialised(template: str, name: str, constants: tuple) -> str:
    """Rules 1 and 2 (they depend on the constants alone, so a generator asks once per set)."""
    text, node = _function_node(template, name)
    first = min([node.lineno] + [d.lineno for d in node.decorator_list])
    source = "".join(text.splitlines(keepends=True)[first - 1:node.end_lineno])
    return _fold_constants(_without_notes(source), dict(constants))


@functools.lru_cache(maxsize=None)
def _expression_text(template: str, name: str) -> str:
    text, node = _function_node(template, name)
    body = [s for s in node.body if not (isinstance(s, ast.Expr) and isinstance(s.value, ast.Constant))]
    if len(body) != 1 or not isinstance(body[0], ast.Return) or body[0].value is None:
        raise ValueError(f"templates/{template}.py:{name} must be a docstring and one return statement")
    expression = ast.get_source_segment(text, body[0].value)
    assert expression is not None, name     # a node of ast.parse has its position
    if "\n" in expression:
        raise ValueError(f"templates/{template}.py:{name}: its expression must stand on one line")
    return expression


# ------------------------------------------------------------------ the three rules

def _tokens(source: str) -> list:
    return list(tokenize.generate_tokens(io.StringIO(source).readline))


@functools.lru_cache(maxsize=1024)
def _names(source: str) -> Tuple[Tuple[str, int, int, int], ...]:
    """(name, row, start column, end column) of each name token of ``source`` (not in strings or comments)."""
    return tuple((t.string, t.start[0], t.start[1], t.end[1]) for t in _tokens(source if source.endswith("\n")
                                                                                   else source + "\n")
                 if t.type == tokenize.NAME)


def _without_notes(source: str) -> str:
    """Rule 1: the source without the comments that stand on lines of their own."""
    lines = source.splitlines(keepends=True)
    notes = {tok.start[0] for tok in _tokens(source)
             if tok.type == tokenize.COMMENT and not lines[tok.start[0] - 1][:tok.start[1]].strip()}
    return "".join(line for k, line in enumerate(lines, 1) if k not in notes)


def _reads_only(test: ast.expr, constants: Mapping[str, Any]) -> bool:
    names = {n.id for n in ast.walk(test) if isinstance(n, ast.Name)}
    return bool(names) and names <= set(constants) and not any(isinstance(n, ast.Call) for n in ast.walk(test))


def _fold_constants(source: str, constants: Mapping[str, Any]) -> str:
    """Rule 2: each ``if`` on constants replaced by the branch it takes; other reads of them by their value."""
    used = set()
    while True:
        tree = ast.parse(source)
        node = next((n for n in ast.walk(tree) if isinstance(n, ast.If) and _reads_only(n.test, constants)), None)
        if node is None:
            break
        used |= {n.id for n in ast.walk(node.test) if isinstance(n, ast.Name)}
        taken = eval(compile(ast.Expression(node.test), "<template>", "eval"), {"__builtins__": {}}, dict(constants))
        lines = source.splitlines(keepends=True)
        branch = node.body if taken else node.orelse
        kept: List[str] = []
        if branch:
            if not taken and isinstance(branch[0], ast.If) and lines[branch[0].lineno - 1].lstrip().startswith("elif"):
                raise ValueError("a template's `if` on constants may not have an `elif`")
            shift = branch[0].col_offset - node.col_offset
            for line in lines[branch[0].lineno - 1:branch[-1].end_lineno]:
                if line.strip() and not line.startswith(" " * shift):
                    raise ValueError(f"a template line cannot be dedented by {shift}: {line!r}")
                kept.append(line[shift:] if line.strip() else line)
        source = "".join(lines[:node.lineno - 1] + kept + lines[node.end_lineno:])
    reads = [n for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Name) and n.id in constants]
    if any(not isinstance(n.ctx, ast.Load) for n in reads):
        raise ValueError("a template may not assign to a compile-time constant")
    lines = source.splitlines(keepends=True)
    for n in sorted(reads, key=lambda n: (n.lineno, n.col_offset), reverse=True):
        encoded = lines[n.lineno - 1].encode()           # ast's columns count UTF-8 bytes
        lines[n.lineno - 1] = (encoded[:n.col_offset] + repr(constants[n.id]).encode()
                               + encoded[n.end_col_offset:]).decode()
        used.add(n.id)
    unused = set(constants) - used
    if unused:
        raise ValueError(f"constants the template does not read: {sorted(unused)}")
    return "".join(lines)


_STATEMENT = re.compile(r"^(?P<indent>[ ]*)(?P<name>[A-Z][A-Z0-9_]*)(\(.*\))?[ ]*(#.*)?\n?$")


def _fill(source: str, fill: Mapping[str, Union[str, Sequence[str]]], where: str) -> str:
    """Rule 3: placeholders on lines of their own replaced by lines, the others by text."""
    for line in source.splitlines():
        m = _STATEMENT.match(line)
        if m and isinstance(fill.get(m.group("name")), str):
            raise ValueError(f"{where}: {m.group('name')} stands for statements; give it a list of lines")
    text = {k: v for k, v in fill.items() if isinstance(v, str)}
    source = _replace_names(source, text, where)       # first: its token positions are cached per source
    out, used = [], set()
    for line in source.splitlines(keepends=True):
        m = _STATEMENT.match(line)
        if m and m.group("name") in fill:
            lines = fill[m.group("name")]
            used.add(m.group("name"))
            out += [(m.group("indent") + s if s else s) + "\n" for s in lines]
        else:
            out.append(line)
    unused = set(fill) - used - set(text)
    if unused:
        raise ValueError(f"{where}: placeholders it does not name: {sorted(unused)}")
    return "".join(out)


def _replace_names(source: str, text: Mapping[str, str], where: str) -> str:
    """``source`` with each name token in ``text`` replaced by its text (not in strings or comments)."""
    if not text:
        return source
    if any("\n" in v for v in text.values()):
        raise ValueError(f"{where}: a placeholder inside a line stands for text of one line")
    lines = source.splitlines(keepends=True) or [""]
    found = [t for t in _names(source) if t[0] in text]
    missing = set(text) - {t[0] for t in found}
    if missing:
        raise ValueError(f"{where}: placeholders it does not name: {sorted(missing)}")
    for name, row, col, end in sorted(found, key=lambda t: t[1:3], reverse=True):
        lines[row - 1] = lines[row - 1][:col] + text[name] + lines[row - 1][end:]
    return "".join(lines)
