"""Run one Python block of a guide as a reader would, and check the values its comments show.

``python harness.py BLOCK.py FIRST_LINE`` executes the block statement by statement in one
namespace (the current directory is the guide's folder). A top-level expression statement whose
line ends in a comment showing a value is checked: ``x  # True`` (a Python literal, before any
``:`` explanation) must equal it, or the value's ``repr`` must be the comment's text. A
``print(...)`` statement with a comment must print exactly the comment's text (or its part
before ``:``). Comments that describe rather than show (``# [SourceError], with positions``) are
not checked. Failures are printed as ``guide-line: message``; the exit code is 1 if any.
"""

from __future__ import annotations

import ast
import contextlib
import io
import sys
import tokenize


def comments(source: str) -> dict[int, str]:
    """Line number -> the text of the comment that ends that line."""
    found = {}
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type == tokenize.COMMENT:
            found[token.start[0]] = token.string[1:].strip()
    return found


def shown(comment: str) -> list[str]:
    """What a comment may show: itself, and its part before an explanation after ``:``."""
    options = [comment]
    head = comment.split(": ", 1)[0].split(" -- ", 1)[0].strip()
    if head != comment:
        options.append(head)
    return options


def literal(text: str):
    try:
        return True, ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
        return False, None


def check_value(value, comment: str) -> str | None:
    """None if ``value`` is what ``comment`` shows (or it shows no value), else why not."""
    options = shown(comment)
    if repr(value) in options or str(value) in options:
        return None
    for option in options:
        ok, expected = literal(option)
        if ok:
            if expected == value:
                return None
            return f"the guide shows {option}, the code gives {value!r}"
    return None  # a description, not a value


def main(path: str, first_line: int) -> int:
    source = open(path, encoding="utf-8").read()
    tree = ast.parse(source, filename=path)
    notes = comments(source)
    namespace: dict = {"__name__": "__main__"}
    failures = []
    for node in tree.body:
        line = first_line + node.lineno
        comment = notes.get(node.end_lineno) if isinstance(node, ast.Expr) else None
        is_print = (
            isinstance(node, ast.Expr)
            and isinstance(node.value, ast.Call)
            and isinstance(node.value.func, ast.Name)
            and node.value.func.id == "print"
        )
        if comment and is_print:
            out = io.StringIO()
            with contextlib.redirect_stdout(out):
                exec(compile(ast.Module([node], []), path, "exec"), namespace)
            printed = out.getvalue().rstrip("\n")
            sys.stdout.write(out.getvalue())
            if printed not in shown(comment):
                failures.append(f"{line}: the guide shows it prints {comment!r}, it printed "
                                f"{printed!r}")
        elif comment:
            value = eval(compile(ast.Expression(node.value), path, "eval"), namespace)
            problem = check_value(value, comment)
            if problem:
                failures.append(f"{line}: {problem}")
        else:
            exec(compile(ast.Module([node], []), path, "exec"), namespace)
    for failure in failures:
        print(f"MISMATCH {failure}", file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], int(sys.argv[2])))
