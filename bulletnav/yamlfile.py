"""Reading the YAML files users write (layouts, sweeps, hyperparameters, benchmark suites).

One reader for all of them, so that every way a file can be unreadable ends in the caller's
own error type with the file named: missing or unreadable, not UTF-8, not YAML (including
Python object tags, which ``yaml.safe_load`` refuses), or nested too deeply for the parser.
"""

from __future__ import annotations

import reprlib
from pathlib import Path
from typing import Any

import yaml

MAX_DEPTH = 64
"""Deepest nesting of mappings and lists accepted (the project's files nest 4 deep). PyYAML's
composer recurses per level: 1,000 levels take a second to end in a RecursionError."""


MAX_VALUES = 1_000_000
"""Most values a document may hold once its aliases are expanded. ``safe_load`` shares an
aliased value instead of copying it, but any code that walks the result (a message, a
``deepcopy``, a JSON record) expands it: nine levels of nine aliases are 387 M values."""


class _Loader(yaml.SafeLoader):
    """``yaml.SafeLoader`` (no Python tags) that refuses nesting deeper than :data:`MAX_DEPTH`
    and documents that expand to more than :data:`MAX_VALUES` values."""

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self._depth = 0
        self._sizes: dict[int, int] = {}  # id(node) -> values it expands to (nodes live while composing)

    def compose_node(self, parent, index):  # type: ignore[no-untyped-def]
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise yaml.composer.ComposerError(None, None, f"nested deeper than {MAX_DEPTH} levels",
                                                  self.peek_event().start_mark)
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        if id(node) not in self._sizes:
            if isinstance(node, yaml.SequenceNode):
                children = node.value
            elif isinstance(node, yaml.MappingNode):
                children = [n for pair in node.value for n in pair]
            else:
                children = []
            size = 1 + sum(self._sizes.get(id(c), 1) for c in children)
            if size > MAX_VALUES:
                raise yaml.composer.ComposerError(None, None, f"expands to more than {MAX_VALUES:,} values "
                                                  "through its aliases", node.start_mark)
            self._sizes[id(node)] = size
        return node

    def construct_object(self, node, deep=False):  # type: ignore[no-untyped-def]
        """PyYAML's, with the position of a value its constructor refuses (``!!int x``: a
        ``ValueError`` without a mark) as a ``ConstructorError`` at the node."""
        try:
            return super().construct_object(node, deep)
        except (ValueError, TypeError, OverflowError) as exc:
            raise yaml.constructor.ConstructorError(None, None, str(exc), node.start_mark) from None


def safe_load(text: str) -> Any:
    """``yaml.safe_load`` with the nesting limit :data:`MAX_DEPTH`."""
    loader = _Loader(text)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()


_SHORT = reprlib.Repr()
_SHORT.maxlevel, _SHORT.maxlist, _SHORT.maxtuple, _SHORT.maxdict = 3, 6, 6, 6
_SHORT.maxstring, _SHORT.maxother, _SHORT.maxlong = 60, 60, 40


def show(value: Any) -> str:
    """A bounded ``repr`` of a value decoded from a file, for error messages: a few levels and
    entries, so that an alias bomb (9^9 shared strings) or a 3000-deep list prints in a line."""
    return _SHORT.repr(value)


def read_yaml(path: str | Path, what: str, error: type[Exception], data: bytes | None = None) -> Any:
    """The decoded YAML document of ``path`` (``data``: its bytes, already read).

    Args:
        path: the file, named in every message.
        what: what the file is, for messages (``"layout file"``).
        error: the exception type to raise (the caller's own, e.g. ``LayoutError``).

    Raises:
        error: ``"<path>: cannot read <what> (...)"``, ``"<path>: not UTF-8 text (...)"``,
            ``"<path>:<line>:<column>: not valid YAML: ..."`` (a syntax error, or a tag, alias or
            nesting refused where it stands) or ``"<path>: not valid YAML (...)"`` (a value no
            constructor takes), on one line.
    """
    path = Path(path)
    if data is None:
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise error(f"{path}: cannot read {what} ({exc.strerror or exc})") from exc
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    try:
        return safe_load(text)
    except yaml.MarkedYAMLError as exc:
        raise error(yaml_message(path, exc)) from None
    except (yaml.YAMLError, ValueError, TypeError, OverflowError) as exc:  # PyYAML's constructors raise the
        # last three for explicit tags on bad values (`!!int x`)
        raise error(f"{path}: not valid YAML ({' '.join(str(exc).split())})") from None
    except RecursionError:
        raise error(f"{path}: not valid YAML (nested too deeply)") from None


def yaml_message(path: str | Path, exc: yaml.MarkedYAMLError) -> str:
    """``FILE:LINE:COL: not valid YAML: problem (context at line L, column C)`` for a PyYAML error
    with a position (lines and columns from 1, as editors and compilers count them), where PyYAML's
    own text names ``"<unicode string>"`` and spreads over several lines."""
    mark = exc.problem_mark or exc.context_mark
    problem = " ".join(str(exc.problem or exc.context or "error").split())
    where = f"{path}:{mark.line + 1}:{mark.column + 1}" if mark is not None else str(path)
    context = ""
    if exc.context and exc.problem and exc.context_mark is not None:
        cm = exc.context_mark
        context = f" ({' '.join(exc.context.split())} that starts at line {cm.line + 1}, column {cm.column + 1})"
    elif exc.context and exc.problem:
        context = f" ({' '.join(exc.context.split())})"
    return f"{where}: not valid YAML: {problem}{context}"
