"""The Python API page of the documentation site, read from the code, never typed.

``mkdocs build`` calls :func:`api_reference` through its hook (``docs/hooks/imply_pages.py``),
which adds the result as ``reference/python-api.md``. The page documents what a world-model
author writes (the model object :func:`imply.evaluate.evaluate` calls and the
:class:`imply.evaluate.RolloutRequest` it passes) and the functions they call from a script
(:data:`SECTIONS`): for each, its signature (``inspect.signature``), its docstring as Markdown
(:func:`imply.docs_pages.rst_to_markdown`) and, for a dataclass, its fields with their types.

Angle brackets and ampersands outside code are written as HTML entities
(:func:`escape_html`), so that a browser shows them rather than reading them as markup.

Nothing here is imported by the package; it sits at the top, beside :mod:`imply.docs_pages`.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import re
import typing
from dataclasses import dataclass
from typing import Any

from imply.docs_pages import rst_to_markdown

LINE = 88  # a signature longer than this is written one parameter per line


@dataclass(frozen=True)
class Entry:
    """One documented name: ``module.name`` as a user imports it."""

    module: str
    name: str

    def resolve(self) -> Any:
        return getattr(importlib.import_module(self.module), self.name)


@dataclass(frozen=True)
class Section:
    """A section of the page: a title, a paragraph of Markdown, a module whose docstring opens it, its entries."""

    title: str
    intro: str
    entries: tuple[Entry, ...]
    module_doc: str | None = None


SECTIONS: tuple[Section, ...] = (
    Section(
        "The model you write",
        "`imply evaluate` (and `evaluate` below) calls an object you write. What it must have, as the module that "
        "checks it says:",
        (
            Entry("imply.evaluate", "RolloutRequest"),
            Entry("imply.evaluate", "WorldModel"),
            Entry("imply.evaluate.interface", "ModelError"),
            Entry("imply.evaluate.interface", "load_model"),
        ),
        module_doc="imply.evaluate.interface",
    ),
    Section(
        "Running an evaluation from Python",
        "The command `imply evaluate` is these calls: load a suite, evaluate one or more models on it, write "
        "the report. A script can make them itself, for example to evaluate a model object it already holds. "
        "The suite's files, a rollouts file and the report's files are described in [File formats](formats.md).",
        (
            Entry("imply.evaluate", "evaluate"),
            Entry("imply.evaluate", "EvaluateConfig"),
            Entry("imply.evaluate", "load_suite"),
            Entry("imply.evaluate.suite", "Suite"),
            Entry("imply.evaluate.evaluation", "Evaluation"),
            Entry("imply.evaluate", "write_report"),
            Entry("imply.evaluate", "write_rollouts_file"),
        ),
    ),
    Section(
        "Scoring slides without a suite",
        "Slides already read from a model's rollouts are scored by `imply.score`, as `imply score` does: "
        "`Scorer(PushTable.load(path))` with the push table (`imply.table.PushTable`), then `score` for many "
        "sets at once.",
        (
            Entry("imply.score", "Scorer"),
            Entry("imply.score", "Scores"),
            Entry("imply.score", "Fit"),
            Entry("imply.score", "score_sets"),
            Entry("imply.score", "ScoreConfig"),
        ),
    ),
)


# -- Markdown text -------------------------------------------------------------------------

_ENTITIES = {"<": "&lt;", ">": "&gt;", "&": "&amp;"}
_CODE_SPAN = re.compile(r"(`+)(.+?)(?<!`)\1(?!`)")
_FENCE = re.compile(r"^\s*(```|~~~)")


# an ampersand that already starts an entity is kept, so that escaping twice changes nothing
_SPECIAL = re.compile(r"\\?(?:[<>]|&(?!(?:[A-Za-z]+|#[0-9]+|#x[0-9A-Fa-f]+);))")


def _escape_text(text: str) -> str:
    # a backslash-escaped bracket (a paragraph that starts with ">") becomes the entity alone
    return _SPECIAL.sub(lambda m: _ENTITIES[m.group()[-1]], text)


def escape_html(markdown: str) -> str:
    """``markdown`` with ``<``, ``>`` and ``&`` written as entities wherever they are not code.

    Fenced code blocks and inline code spans are kept as they are: Markdown escapes them itself.
    An entity already written stays as it is, so the function may be applied twice.
    """
    out: list[str] = []
    fence: str | None = None
    for line in markdown.split("\n"):
        m = _FENCE.match(line)
        if fence is not None:
            if m and m.group(1) == fence:
                fence = None
            out.append(line)
            continue
        if m:
            fence = m.group(1)
            out.append(line)
            continue
        parts, last = [], 0
        for span in _CODE_SPAN.finditer(line):
            parts += [_escape_text(line[last : span.start()]), span.group()]
            last = span.end()
        out.append("".join([*parts, _escape_text(line[last:])]))
    return "\n".join(out)


def _hanging_joined(doc: str) -> str:
    """``doc`` with the hanging indents of ``name: text`` paragraphs undone.

    The package's docstrings describe arguments and fields as ``name: text`` paragraphs whose
    long entries continue on a line indented deeper; that line is part of the paragraph, not a
    definition or a literal block, so it is moved to the paragraph's indent.
    """
    lines = doc.split("\n")
    out: list[str] = []
    start: str | None = None  # the first line of the current paragraph
    for line in lines:
        if not line.strip():
            start = None
            out.append(line)
            continue
        if start is None:
            start = line
            out.append(line)
            continue
        indent = len(start) - len(start.lstrip())
        deeper = len(line) - len(line.lstrip()) > indent
        stripped = line.lstrip()
        if (
            deeper
            and re.match(r"\s*[A-Za-z_][\w, ]*: ", start)
            and not stripped.startswith(("* ", "- "))
            and not out[-1].rstrip().endswith("::")
        ):
            out.append(" " * indent + stripped)
        else:
            out.append(line)
    return "\n".join(out)


def docstring(obj: Any) -> str:
    """The docstring of ``obj`` itself (not one it inherits) as Markdown, or ''."""
    if inspect.isclass(obj):
        raw = obj.__dict__.get("__doc__")
    else:
        raw = getattr(obj, "__doc__", None)
    if not raw or not raw.strip():
        return ""
    return rst_to_markdown(_hanging_joined(inspect.cleandoc(raw)))


def _cell(text: str) -> str:
    """Text for a Markdown table cell: one line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _code(text: str) -> str:
    """Text as an inline code span (pipes escaped for a table)."""
    s = " ".join(str(text).split()).replace("|", "\\|")
    tick = "``" if "`" in s else "`"
    return f"{tick}{s}{tick}" if s else ""


# -- signatures ----------------------------------------------------------------------------


class _Annotation:
    """An annotation shown as written in the source (the package's annotations are strings)."""

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text


def _shown(annotation: Any) -> Any:
    if annotation is inspect.Parameter.empty:
        return annotation
    if isinstance(annotation, str):
        return _Annotation(annotation)
    return _Annotation(inspect.formatannotation(annotation))


def type_text(annotation: Any) -> str:
    """An annotation as written: a string as it is, a type by its name."""
    return annotation if isinstance(annotation, str) else inspect.formatannotation(annotation)


def signature(name: str, obj: Any, *, drop_first: bool = False) -> str:
    """``name(parameters) -> return`` of ``obj``, one parameter per line when it is long (a class: no return)."""
    sig = inspect.signature(obj)
    if inspect.isclass(obj):
        sig = sig.replace(return_annotation=inspect.Signature.empty)
    params = list(sig.parameters.values())
    if drop_first and params and params[0].name in ("self", "cls"):
        params = params[1:]
    words: list[str] = []
    positional_only = False
    star_needed = True
    for p in params:
        if p.kind is p.POSITIONAL_ONLY:
            positional_only = True
        elif positional_only:
            words.append("/")
            positional_only = False
        if p.kind is p.VAR_POSITIONAL:
            star_needed = False
        elif p.kind is p.KEYWORD_ONLY and star_needed:
            words.append("*")
            star_needed = False
        words.append(str(p.replace(annotation=_shown(p.annotation))))
    if positional_only:
        words.append("/")
    returns = sig.return_annotation
    tail = "" if returns is inspect.Signature.empty else f" -> {type_text(returns)}"
    one_line = f"{name}({', '.join(words)}){tail}"
    if len(one_line) <= LINE or not words:
        return one_line
    return f"{name}(\n" + "".join(f"    {w},\n" for w in words) + f"){tail}"


def _code_block(text: str) -> list[str]:
    return ["```python", text, "```", ""]


# -- one documented name -------------------------------------------------------------------


def _where(entry: Entry, obj: Any) -> str:
    defined = getattr(obj, "__module__", entry.module)
    line = f"`from {entry.module} import {entry.name}`"
    return line + (f" (defined in `{defined}`)." if defined != entry.module else ".")


def _default(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        return _code(repr(f.default))
    if f.default_factory is not dataclasses.MISSING:
        return _code(repr(f.default_factory()))
    return "required"


def fields_table(cls: type) -> list[str]:
    """The fields of dataclass ``cls``: name, type, and the default and doc where any field has one."""
    fields = dataclasses.fields(cls)
    with_default = any(
        f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING for f in fields
    )
    with_doc = any(f.metadata.get("doc") for f in fields)
    head = ["field", "type", *(["default"] if with_default else []), *(["doc"] if with_doc else [])]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for f in fields:
        row = [_code(f.name), _code(type_text(f.type))]
        if with_default:
            row.append(_default(f))
        if with_doc:
            row.append(_cell(f.metadata.get("doc", "")))
        out.append("| " + " | ".join(row) + " |")
    return [*out, ""]


def _bases(cls: type) -> list[str]:
    shown = [b for b in cls.__bases__ if b not in (object, typing.Protocol, typing.Generic)]
    if typing.Protocol in cls.__bases__:
        return ["A protocol: any object with these attributes and methods will do; it need not subclass it.", ""]
    if not shown:
        return []
    names = ", ".join(_code(f"{b.__module__}.{b.__qualname__}") for b in shown)
    return [f"Subclass of {names}.", ""]


def _members(cls: type) -> list[str]:
    """The public methods and properties ``cls`` defines itself, in source order."""
    out: list[str] = []
    for name, member in cls.__dict__.items():
        if name.startswith("_"):
            continue
        if isinstance(member, property):
            returns = inspect.signature(member.fget).return_annotation
            kind = "" if returns is inspect.Signature.empty else f": {type_text(returns)}"
            out += [f"#### `{cls.__name__}.{name}`", "", *_code_block(f"{name}{kind}  # property")]
            doc = docstring(member.fget)
        elif isinstance(member, classmethod | staticmethod) or inspect.isfunction(member):
            func = member.__func__ if isinstance(member, classmethod | staticmethod) else member
            drop = not isinstance(member, staticmethod)
            out += [f"#### `{cls.__name__}.{name}`", "", *_code_block(signature(name, func, drop_first=drop))]
            doc = docstring(func)
        else:
            continue
        if doc:
            out += [doc.strip(), ""]
    return out


def _protocol_attributes(cls: type) -> list[str]:
    hints = cls.__dict__.get("__annotations__", {})
    if not hints:
        return []
    out = ["| attribute | type |", "|---|---|"]
    out += [f"| {_code(name)} | {_code(type_text(hint))} |" for name, hint in hints.items()]
    return [*out, ""]


def document(entry: Entry) -> list[str]:
    """The Markdown of one name: heading, where to import it from, signature, docstring, fields, members."""
    obj = entry.resolve()
    out = [f"### `{entry.name}`", "", _where(entry, obj), ""]
    if inspect.isclass(obj):
        is_protocol = typing.Protocol in obj.__bases__
        if issubclass(obj, BaseException):
            out += _code_block(f"class {obj.__name__}({obj.__bases__[0].__name__})")
        elif not is_protocol:
            init = obj.__dict__.get("__init__")
            if dataclasses.is_dataclass(obj) or init is not None:
                out += _code_block(signature(obj.__name__, obj))
        out += _bases(obj) if not issubclass(obj, BaseException) else []
        doc = docstring(obj)
        if doc:
            out += [doc.strip(), ""]
        init = obj.__dict__.get("__init__")
        if init is not None and not dataclasses.is_dataclass(obj) and docstring(init):
            out += [docstring(init).strip(), ""]
        if dataclasses.is_dataclass(obj):
            out += ["Fields:", "", *fields_table(obj)]
        if is_protocol:
            out += _protocol_attributes(obj)
        out += _members(obj)
    else:
        out += _code_block(signature(entry.name, obj))
        doc = docstring(obj)
        if doc:
            out += [doc.strip(), ""]
    return out


def _output_kinds() -> list[str]:
    from imply.evaluate.interface import KINDS, OUTPUT_SHAPES

    out = [
        "### Output kinds",
        "",
        "What `rollout` returns for each `kind` (`imply.evaluate.interface.OUTPUT_SHAPES`):",
        "",
    ]
    out += ["| `kind` | `rollout(request)` returns |", "|---|---|"]
    out += [f"| {_code(kind)} | {_cell(OUTPUT_SHAPES[kind])} |" for kind in KINDS]
    return [*out, ""]


def api_reference() -> str:
    """The Python API page (``reference/python-api.md``): every name of :data:`SECTIONS`, documented from the code."""
    out = [
        "# Python API",
        "",
        "The interface a world-model author implements, and the functions they call from Python. This page is "
        "generated from the code when the site is built (`imply.docs_api`): signatures, docstrings and fields "
        "cannot drift from it. The tutorial [Evaluate your world model](../tutorials/evaluate.md) builds a "
        "complete model step by step; the [command line](cli.md) runs the same functions.",
        "",
    ]
    for section in SECTIONS:
        out += [f"## {section.title}", "", section.intro, ""]
        if section.module_doc:
            module = importlib.import_module(section.module_doc)
            out += [f"*Module `{section.module_doc}`*", "", docstring(module).strip(), ""]
            out += _output_kinds()
        for entry in section.entries:
            out += document(entry)
    page = "\n".join(out)
    return escape_html(re.sub(r"\n{3,}", "\n\n", page)).rstrip() + "\n"
