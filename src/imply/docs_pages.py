"""The documentation site's generated pages, read from the code and from ``results/``, never typed.

``mkdocs build`` calls this module through its hook (``docs/hooks/imply_pages.py``):

* :func:`config_reference`: every config key, walked from :class:`imply.workflow_config.StudyConfig`
  (the settings classes the schema is written from): type, default, bounds, doc;
* :func:`cli_reference`: every command and option, walked from :func:`imply.cli.build_parser`;
* :func:`formats_reference`: every file format, from the docstrings and column lists of the
  modules that read or write it (:data:`FORMATS`);
* :func:`status_page`: the reproduction status, from ``results/paper/reproduction.md`` and
  ``results/paper/numbers.json`` when the study has run (and saying so when it has not).

Hand-written pages may hold *placeholders*, ``{{ name argument }}``, replaced at build time by
:func:`expand` (:data:`PLACEHOLDERS`): a config value, a figure from ``results/`` (copied into
the site when present), the per-stage time of the last run, the stand-ins' known answers. An
unknown placeholder is an error, so a typo never reaches the site.

Nothing here is imported by the package; it sits at the top, beside :mod:`imply.cli`.
"""

from __future__ import annotations

import argparse
import dataclasses
import html
import importlib
import json
import math
import os
import re
import textwrap
import types
import typing
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
FIGURES = "figures"  # the site folder that figures copied from results/ go to

# -- small Markdown helpers ---------------------------------------------------------


# A code span: a run of backticks, text, the same run again (CommonMark's rule).
_CODE_SPAN = re.compile(r"(?<!`)(`+)(?!`)(.+?)(?<!`)\1(?!`)", re.S)


def escape_html(text: Any) -> str:
    """Text with ``&``, ``<`` and ``>`` as entities, except inside code spans (Markdown escapes those itself).

    Generated text comes from docstrings, help strings and docs that mean ``<stem>.json`` as
    words; unescaped, a browser would take ``<stem>`` for a tag and show nothing.
    """
    s, out, pos = str(text), [], 0
    for m in _CODE_SPAN.finditer(s):
        out += [html.escape(s[pos : m.start()], quote=False), m.group(0)]
        pos = m.end()
    return "".join([*out, html.escape(s[pos:], quote=False)])


def cell(text: Any) -> str:
    """Text for a Markdown table cell: one line, pipes escaped, ``&<>`` escaped outside code spans."""
    return escape_html(" ".join(str(text).split())).replace("|", "\\|")


def code(text: Any) -> str:
    """Text as an inline code span inside a table cell (pipes escaped; Markdown escapes ``&<>`` in it)."""
    s = " ".join(str(text).split()).replace("|", "\\|")
    tick = "``" if "`" in s else "`"
    pad = " " if s.startswith("`") or s.endswith("`") else ""
    return f"{tick}{pad}{s}{pad}{tick}" if s else ""


def _escape_markdown(markdown: str) -> str:
    """Markdown with ``&<>`` escaped outside fenced blocks and code spans (one paragraph per line)."""
    out, fenced = [], False
    for line in markdown.split("\n"):
        if line.lstrip().startswith("```"):
            fenced = not fenced
            out.append(line)
        else:
            out.append(line if fenced else escape_html(line))
    return "\n".join(out)


_ROLE = re.compile(r":(?:[a-z]+:)+`~?([^`<]*?)(?:\s*<([^`>]*)>)?`")


def rst_to_markdown(text: str, escape: bool = False) -> str:
    """A docstring (the reStructuredText subset the package writes) as Markdown.

    Roles (``:func:`x```) become code spans, double backticks single ones, ``::`` blocks
    fenced code, definition lists (a term, then its indented text) Markdown's, bullets
    Markdown's (nested by indent); paragraphs are joined into one line each. With ``escape``,
    ``&``, ``<`` and ``>`` outside code spans and fenced blocks become entities, so that a
    docstring's ``<stem>.json`` shows as written rather than as an unknown HTML tag (the
    reference pages' text; a caption that ends up in an attribute or a title wants it unescaped).
    """
    text = _ROLE.sub(lambda m: f"`{(m.group(1) or m.group(2)).strip()}`", textwrap.dedent(text).strip("\n"))
    text = re.sub(r"``([^`]+?)``", r"`\1`", text)
    lines = text.splitlines()
    out: list[str] = []

    def indent_of(line: str) -> int:
        return len(line) - len(line.lstrip())

    def bullet(line: str) -> bool:
        return line.lstrip().startswith(("* ", "- "))

    def deeper(start: int, base: int) -> int:
        """The index after the lines from ``start`` indented deeper than ``base`` (blank lines inside kept)."""
        j = start
        while j < len(lines) and (not lines[j].strip() or indent_of(lines[j]) > base):
            j += 1
        while j > start and not lines[j - 1].strip():
            j -= 1
        return j

    def safe(paragraph: str) -> str:  # escaped, a leading '>' is &gt; and no quote already
        return "\\" + paragraph if paragraph[:1] in (("#", "+") if escape else (">", "#", "+")) else paragraph

    bullets: list[int] = []  # indents of the open bullet levels
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.strip():
            out.append("")
            i += 1
            continue
        if bullet(line):
            ind = indent_of(line)
            while bullets and bullets[-1] > ind:
                bullets.pop()
            if not bullets or bullets[-1] < ind:
                bullets.append(ind)
            j = i + 1
            while j < len(lines) and lines[j].strip() and indent_of(lines[j]) > ind and not bullet(lines[j]):
                j += 1
            item = " ".join(x.strip() for x in [line.lstrip()[2:], *lines[i + 1 : j]])
            if len(bullets) == 1 and out and out[-1].strip() and not out[-1].lstrip().startswith("- "):
                out.append("")
            out.append("    " * (len(bullets) - 1) + "- " + item)
            i = j
            continue
        bullets = []
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        if nxt.strip() and indent_of(nxt) > indent_of(line) and not bullet(nxt):
            end = deeper(i + 1, indent_of(line))
            out += ["", line.strip(), ":   " + " ".join(" ".join(lines[i + 1 : end]).split()), ""]
            i = end
            continue
        j = i
        while j < len(lines) and lines[j].strip() and not bullet(lines[j]):
            j += 1
            if lines[j - 1].rstrip().endswith("::") or (
                j < len(lines) and lines[j].strip() and indent_of(lines[j]) > indent_of(lines[i])
            ):
                break
        if out and out[-1].strip():
            out.append("")
        paragraph = " ".join(x.strip() for x in lines[i:j])
        if paragraph.endswith("::"):  # a literal block follows
            paragraph = paragraph[:-2].rstrip()
            if paragraph:
                out.append(safe(paragraph) + ":")
            k = j
            while k < len(lines) and not lines[k].strip():
                k += 1
            end = deeper(k, indent_of(lines[j - 1]))
            out += ["", "```text", *textwrap.dedent("\n".join(lines[k:end])).splitlines(), "```", ""]
            j = end
        else:
            out.append(safe(paragraph))
        i = j
    markdown = re.sub(r"\n{3,}", "\n\n", "\n".join(out)).strip()
    return (_escape_markdown(markdown) if escape else markdown) + "\n"


# -- the config reference ----------------------------------------------------------


@dataclass(frozen=True)
class ConfigKey:
    """One config key: its dotted name, type, default (as JSON text, or ``required``), bounds and doc."""

    key: str
    type: str
    default: str
    bounds: str
    doc: str
    depth: int


def _is_settings(hint: Any) -> bool:
    from imply.options import Config

    return isinstance(hint, type) and issubclass(hint, Config)


def _plural(word: str) -> str:
    return {"number": "numbers", "integer": "integers", "text": "texts", "boolean": "booleans"}.get(word, word)


def type_name(hint: Any) -> str:
    """A type hint in words: ``number``, ``list of 3 numbers``, ``mapping of text to text``, ``X or null``."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(type_name(a) for a in args)
    if hint is type(None):
        return "null"
    if _is_settings(hint):
        return f"settings ({hint.__name__})"
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"list of {_plural(type_name(args[0]))}"
        if len(set(args)) == 1:
            return f"list of {len(args)} {_plural(type_name(args[0]))}"
        return "list (" + ", ".join(type_name(a) for a in args) + ")"
    if origin is dict:
        return f"mapping of {type_name(args[0])} to {type_name(args[1])}" if args else "mapping"
    if origin is list:
        return f"list of {type_name(args[0])}" if args else "list"
    if hint is Any:
        return "any"
    return {bool: "boolean", int: "integer", float: "number", str: "text"}.get(
        hint, getattr(hint, "__name__", str(hint))
    )


def _plain(value: Any) -> Any:
    from imply.options import Config

    if isinstance(value, Config):
        return value.to_dict()
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


def _json(value: Any) -> str:
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    return json.dumps(_plain(value), default=str, ensure_ascii=False)


_BOUND_WORDS = {
    "minimum": "≥ {}",
    "maximum": "≤ {}",
    "exclusive_minimum": "> {}",
    "exclusive_maximum": "< {}",
    "choices": "one of {}",
    "min_items": "at least {} items",
    "max_items": "at most {} items",
    "unique": "no repeats",
    "pattern": "matches {}",
}


def _bound_words(bounds: dict[str, Any]) -> list[str]:
    out = []
    for key, value in bounds.items():
        if key == "unique" and not value:
            continue
        shown = ", ".join(map(str, value)) if key == "choices" else value
        out.append(_BOUND_WORDS[key].format(shown))
    return out


def bounds_text(metadata: Any) -> str:
    """A field's bounds in words (its value's, each item's, the keys it may have)."""
    if not metadata:
        return ""
    parts = _bound_words(metadata.get("bounds", {}))
    items = _bound_words(metadata.get("items", {}))
    if items:
        parts.append("each " + ", ".join(items))
    if metadata.get("keys") is not None:
        parts.append("keys: " + ", ".join(metadata["keys"]))
    if metadata.get("required"):
        parts.append("must be in config.yaml")
    return "; ".join(parts)


def config_keys(cls: type | None = None, prefix: str = "", instance: Any = None, depth: int = 0) -> list[ConfigKey]:
    """Every key of settings class ``cls`` (default: the whole study config), nested keys dotted, in order.

    Defaults come from ``instance`` (the parent's default), else the field's own default. A
    mapping of settings (``model.presets``) is described once per entry of its default, a
    union with settings (``encoder.arch``: a name or a mapping) gives the mapping's keys too.
    """
    from imply.options import Config

    if cls is None:
        from imply.workflow_config import StudyConfig

        cls = StudyConfig
    if instance is None:
        try:
            instance = cls()
        except TypeError:  # a class with required fields: defaults field by field
            instance = None
    hints = typing.get_type_hints(cls)
    out: list[ConfigKey] = []
    for f in dataclasses.fields(cls):
        hint = hints[f.name]
        key = f"{prefix}{f.name}"
        has_default = f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING
        value = getattr(instance, f.name) if instance is not None else None
        if instance is None and has_default:
            value = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        known = instance is not None or has_default
        nested = [a for a in (hint, *typing.get_args(hint)) if _is_settings(a)]
        default = "required" if not known else ("" if isinstance(value, Config) else _json(value))
        out.append(ConfigKey(key, type_name(hint), default, bounds_text(f.metadata), f.metadata.get("doc", ""), depth))
        if nested and typing.get_origin(hint) is not dict:
            sub = nested[0]
            out += config_keys(sub, f"{key}.", value if isinstance(value, sub) else None, depth + 1)
        elif typing.get_origin(hint) is dict and nested:
            sub = nested[0]
            for name, entry in (value or {}).items():
                out += config_keys(sub, f"{key}.{name}.", entry, depth + 1)
    return out


def config_reference() -> str:
    """The config reference page: one table per top-level section of ``config.yaml``."""
    from imply.workflow_config import StudyConfig

    keys = config_keys()
    hints = typing.get_type_hints(StudyConfig)
    out = [
        "# Configuration reference",
        "",
        "Every key of `config.yaml`, generated when the site is built from the settings classes "
        "(`imply.workflow_config.StudyConfig` and the classes it names), the same source the workflow's schema "
        "`workflow/schemas/config.schema.yaml` and the command line's defaults are written from. *Default* is "
        "the study's value; *required* means the key has no default. A run's own file overrides any of them: "
        "`snakemake --configfile my.yaml` or `--config key=value`. An unknown key at any level is refused "
        "when Snakemake reads the workflow, with the nearest known name.",
        "",
        "Beyond each key's type and bounds, `imply.config_check` checks rules across keys when the workflow is "
        "read (so `snakemake -n` already refuses a bad config, in one line naming the key): every range ordered, "
        "query and calibration speeds inside the table's speed range, the selection's query speed among the query "
        "speeds, enough jitter draws for the selection's candidates, candidate and benchmark effects known, the "
        "model preset among the presets, released encoder weights present and of the right shapes, and the scene "
        "compiled once by MuJoCo (which catches unknown `scene.option` attributes).",
        "",
    ]
    for f in dataclasses.fields(StudyConfig):
        hint = hints[f.name]
        section = [k for k in keys if k.key == f.name or k.key.startswith(f.name + ".")]
        doc = f.metadata.get("doc", "")
        out += [f"## `{f.name}`", "", escape_html(doc[:1].upper() + doc[1:] + ".")]
        nested = [a for a in (hint, *typing.get_args(hint)) if _is_settings(a)]
        if nested and nested[0].__doc__:
            first = " ".join(nested[0].__doc__.strip().split("\n\n")[0].split())
            where = f"`{nested[0].__module__}.{nested[0].__name__}`"
            out += ["", f"{rst_to_markdown(first, escape=True).strip()} ({where})"]
        out += ["", "| key | type | default | bounds | doc |", "|---|---|---|---|---|"]
        for k in section:
            out.append(f"| {code(k.key)} | {cell(k.type)} | {code(k.default)} | {cell(k.bounds)} | {cell(k.doc)} |")
        out.append("")
    return "\n".join(out)


# -- the command-line reference ----------------------------------------------------


@dataclass(frozen=True)
class Command:
    """One command of ``imply``: its words (``["sim", "pushes"]``), its parser and its one-line help."""

    words: tuple[str, ...]
    parser: argparse.ArgumentParser
    help: str
    children: list[Command] = field(default_factory=list)

    @property
    def name(self) -> str:
        return " ".join(("imply", *self.words))


def commands(parser: argparse.ArgumentParser | None = None, words: tuple[str, ...] = (), help: str = "") -> Command:
    """The command tree of ``imply`` (default: :func:`imply.cli.build_parser`), in the parsers' own order."""
    if parser is None:
        from imply.cli import build_parser

        parser = build_parser()
        help = parser.description or ""
    node = Command(words, parser, help)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            for name, sub in action.choices.items():
                node.children.append(commands(sub, (*words, name), helps.get(name, "")))
    return node


def walk_commands(node: Command) -> list[Command]:
    return [node, *(c for child in node.children for c in walk_commands(child))]


# A settings default named in a help string: ``(default: TableCheckConfig.cells)``.
_DEFAULT_REF = re.compile(r"\b(default:?\s+)([A-Z]\w*)\.([a-z_]\w*)\b")


def settings_classes() -> dict[str, type]:
    """Every settings class (a subclass of :class:`imply.options.Config`) by name, the study's and their own."""
    import imply.workflow_config  # noqa: F401  (imports every settings class the study names)
    from imply.options import Config

    out: dict[str, type] = {}
    todo = [Config]
    while todo:
        cls = todo.pop()
        for sub in cls.__subclasses__():
            out.setdefault(sub.__name__, sub)
            todo.append(sub)
    return out


_NO_DEFAULT = object()


def settings_default(class_name: str, name: str) -> Any:
    """The default of field ``name`` of settings class ``class_name``, or ``_NO_DEFAULT`` (no such class or field)."""
    from imply.options import default_of

    cls = settings_classes().get(class_name)
    if cls is None or name not in {f.name for f in dataclasses.fields(cls)}:
        return _NO_DEFAULT
    try:
        return default_of(cls, name)
    except ValueError:  # a required field
        return _NO_DEFAULT


def _shown(value: Any) -> str:
    """A default as the page shows it: a text as itself, anything else as JSON."""
    return value if isinstance(value, str) else _json(value)


def _help(action: argparse.Action, parser: argparse.ArgumentParser) -> str:
    """An option's help: ``%(default)s`` and the like filled in, a settings default it names
    (``TableCheckConfig.cells``) replaced by its value (a code span)."""
    text = action.help or ""
    if "%(" in text:
        try:
            text = text % {**vars(action), "prog": parser.prog}
        except (KeyError, TypeError, ValueError):
            pass

    def value(m: re.Match) -> str:
        found = settings_default(m.group(2), m.group(3))
        return m.group(0) if found is _NO_DEFAULT else m.group(1) + code(_shown(found)).replace("\\|", "|")

    return _DEFAULT_REF.sub(value, text)


def _usage(parser: argparse.ArgumentParser) -> str:
    before = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"
    try:
        return parser.format_usage().strip()
    finally:
        if before is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = before


def options_of(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """A parser's own arguments and options (not its help, not its subcommands)."""
    return [a for a in parser._actions if not isinstance(a, argparse._SubParsersAction | argparse._HelpAction)]


def _default(action: argparse.Action) -> str:
    """An option's default (a code span): its parser's, else the settings default its help names, else none."""
    if action.required or isinstance(action, argparse._StoreTrueAction | argparse._StoreFalseAction):
        return ""
    if action.default is argparse.SUPPRESS:
        return ""
    if action.default is None:
        m = _DEFAULT_REF.search(action.help or "")
        found = settings_default(m.group(2), m.group(3)) if m else _NO_DEFAULT
        return "" if found is _NO_DEFAULT or found is None else code(_shown(found))
    return code(_shown(action.default))


def cli_reference() -> str:
    """The command-line reference page: every command of ``imply`` with its usage and every option."""
    tree = commands()
    out = [
        "# Command-line reference",
        "",
        "Every command and option of `imply`, generated when the site is built from the command line's own "
        "parsers (`imply.cli.build_parser`). `imply COMMAND --help` prints the same. Defaults that come from a "
        "settings class are that class's (see the [configuration reference](config.md)). A user error (bad "
        "input, bad option, an output that would overwrite an input) is one line on stderr and exit status 2.",
        "",
    ]
    for node in walk_commands(tree):
        level = "#" * min(2 + max(len(node.words) - 1, 0), 4)
        out += [f"{level} `{node.name}`", ""]
        text = node.parser.description if node.words else node.help
        sentence = ""
        if node.help and node.words:
            sentence = node.help[:1].upper() + node.help[1:] + ("" if node.help.endswith(".") else ".")
            out += [escape_html(sentence), ""]
        # a command without a description of its own shows its help as one (imply.cli): said once here
        if text and text != node.help and text != sentence:
            out += [rst_to_markdown(text, escape=True).strip(), ""]
        out += ["```text", _usage(node.parser), "```", ""]
        actions = options_of(node.parser)
        if node.children:
            out += ["| command | what it does |", "|---|---|"]
            out += [f"| [`{c.name}`](#{anchor(c.name)}) | {cell(c.help)} |" for c in node.children]
            out.append("")
        if actions:
            out += ["| argument | default | help |", "|---|---|---|"]
            for a in actions:
                if a.option_strings:
                    name = ", ".join(code(o) for o in a.option_strings)
                    if a.nargs != 0:
                        name += " " + cell(a.metavar or a.dest.upper())
                else:
                    name = code(a.metavar or a.dest)
                req = " (required)" if a.required and a.option_strings else ""
                choices = f" One of: {', '.join(map(str, a.choices))}." if a.choices else ""
                out.append(f"| {name}{req} | {_default(a)} | {cell(_help(a, node.parser) + choices)} |")
            out.append("")
    return "\n".join(out)


def anchor(title: str) -> str:
    """The id MkDocs' toc gives a heading (its default slugify)."""
    from markdown.extensions.toc import slugify

    return slugify(title, "-")


# -- the file formats --------------------------------------------------------------


@dataclass(frozen=True)
class Format:
    """A file format: its title, the module that reads or writes it, and the column or file lists it names."""

    title: str
    module: str
    names: tuple[str, ...] = ()
    what: str = ""


FORMATS: tuple[Format, ...] = (
    Format(
        "Push log (`imply diagnose`)",
        "imply.diagnose.inputs.pushlog",
        ("REQUIRED", "OPTIONAL_NUMERIC"),
        "what a robot records: one row per push",
    ),
    Format(
        "The box's track beside a push log (`imply diagnose --track`)",
        "imply.diagnose.inputs.track_file",
        ("REQUIRED", "OPTIONAL_NUMERIC"),
        "where each pushed box was over time, one row per frame",
    ),
    Format(
        "Calibration probes beside a push log (`<log>.probes.csv`, `imply sim pushes --probes`)",
        "imply.diagnose.inputs.probes",
        ("KINDS", "NUMERIC"),
        "what a lab measures besides its pushes, one row per probe",
    ),
    Format(
        "A reference session (`imply diagnose --reference`)",
        "imply.diagnose.inference.sessions",
        (),
        "a push log of the same robot and boxes, recorded before the change to explain",
    ),
    Format(
        "Pushes to simulate (`imply sim pushes`)", "imply.sim.push_file", (), "the pushes a simulated push log holds"
    ),
    Format(
        "Rollouts to score (`imply score`)",
        "imply.score_file",
        ("ROLES", "SCORE_COLUMNS"),
        "a model's rollouts read as slides, and the scores written back",
    ),
    Format("User tables in general (CSV or parquet)", "imply.input_files", ("PARQUET_SUFFIXES",)),
    Format(
        "The evaluation suite (`imply suite build`)", "imply.evaluate.suite", ("FILES", "SUITE_ARRAYS", "TRUTH_ARRAYS")
    ),
    Format(
        "The suite as files (`imply suite export`) and generated videos (`imply evaluate --videos`)",
        "imply.evaluate.video_package",
    ),
    Format("Rollouts made elsewhere (`imply evaluate --rollouts`)", "imply.evaluate.rollouts_file", ("CSV_COLUMNS",)),
    Format("The report of `imply evaluate`", "imply.evaluate.report", ("REPORT_FILES",)),
    Format("The report of `imply diagnose`", "imply.diagnose.report", ("REPORT_FILES",)),
    Format("The next pushes (`next_pushes.csv`)", "imply.diagnose.conclusion.next_pushes"),
    Format(
        "The corrected scene (`corrected.xml`)",
        "imply.sim.correction",
        ("CAUSES",),
        "the scene a log was diagnosed against, with the stated causes written in",
    ),
    Format("The push table (`results/table/table.npz`)", "imply.table"),
    Format("Result documents (`results/**/*.json`)", "imply.paper.results"),
    Format("Macros and numbers (`results/paper/macros.tex`, `numbers.json`)", "imply.paper.macros"),
    Format("The reproduction report (`results/paper/reproduction.md`, `.csv`)", "imply.paper.report"),
)


def formats_reference() -> str:
    """The file formats page: each format's module docstring and the column or file lists it names."""
    out = [
        "# File formats",
        "",
        "Every file IMPLY reads from you or writes for you, generated when the site is built from the docstring "
        "and the column lists of the module that reads or writes it (the module named under each title), so "
        "the page and the code cannot drift apart.",
        "",
    ]
    for fmt in FORMATS:
        module = importlib.import_module(fmt.module)
        what = f": {escape_html(fmt.what)}." if fmt.what else "."
        out += [f"## {escape_html(fmt.title)}", "", f"*Module `{fmt.module}`*{what}", ""]
        out += [rst_to_markdown(module.__doc__ or "(no docstring)", escape=True), ""]
        for name in fmt.names:
            value = getattr(module, name)
            shown = ", ".join(f"`{v}`" for v in value) if isinstance(value, list | tuple) else f"`{value}`"
            out += [f"- `{name}`: {shown}"]
        if fmt.names:
            out.append("")
    return "\n".join(out)


# -- results: the reproduction status, figures, times ------------------------------


def _when(path: Path) -> str:
    return datetime.fromtimestamp(path.stat().st_mtime, UTC).strftime("%Y-%m-%d %H:%M UTC")


def snapshot_note(stamp: dict, page: str) -> str:
    """The admonition that says a page shows the committed snapshot, not this checkout's run."""
    from imply.paper.snapshot import label

    return (
        f'!!! info "A snapshot of one run"\n    This checkout has not run the study, so this shows the snapshot '
        f"committed with the documentation: {escape_html(label(stamp))}. Run the study "
        f"([tutorial]({_relative(page, 'tutorials/reproduce.md')})) and build the site again to see your own."
    )


def _snapshot(root: Path) -> tuple[Path, dict] | None:
    """The committed snapshot's folder and stamp (:mod:`imply.paper.snapshot`), or None."""
    from imply.paper.snapshot import SNAPSHOT_DIR, read_stamp

    folder = root / SNAPSHOT_DIR
    stamp = read_stamp(folder)
    return None if stamp is None else (folder, stamp)


def result_file(root: Path, rel: str) -> tuple[Path, dict | None] | None:
    """``rel`` (a path under ``results/``) from this checkout's run, or else from the snapshot (with its stamp), or
    None."""
    if (root / rel).is_file():
        return root / rel, None
    snap = _snapshot(root)
    if snap is not None and (snap[0] / rel).is_file():
        return snap[0] / rel, snap[1]
    return None


def status_page(root: Path = ROOT) -> str:
    """The reproduction status: ``results/paper/reproduction.md`` as the last run wrote it, else the snapshot's, or
    why there is none."""
    from imply.paper.snapshot import claims_sentence

    found = result_file(root, "results/paper/reproduction.md")
    report = found[0] if found else root / "results" / "paper" / "reproduction.md"
    numbers = report.with_name("numbers.json")
    out = ["# Reproduction status", ""]
    if found is not None and found[1] is not None:
        stamp = found[1]
        body = re.sub(r"^# .*\n", "", report.read_text(), count=1)
        body = re.sub(r"^(#+) ", lambda m: "#" + m.group(1) + " ", body, flags=re.M)
        return "\n".join(
            [
                *out,
                snapshot_note(stamp, "status.md"),
                "",
                f"In that run {claims_sentence(stamp)}.",
                "",
                body,
            ]
        )
    if not report.is_file():
        return "\n".join(
            [
                *out,
                '!!! note "The study has not run in this checkout"',
                "    This page is generated from `results/paper/reproduction.md` and `results/paper/numbers.json`, "
                "which the study writes. Neither is here yet, so there is nothing to report. Run the study "
                "([tutorial](tutorials/reproduce.md)), then build the site again: `snakemake --cores 2 && mkdocs build`.",
                "",
                "The reproduction report puts every number the paper prints beside the reproduced one (*matches*, "
                "*close*, *differs*, *not produced*) and marks every claim of every stage *holds* or *fails*. Claims "
                "that fail are reported, never tuned away. Earlier runs are recorded in the "
                "[notes](notes/study-runs.md).",
                "",
            ]
        )
    out += [f"Generated from `results/paper/reproduction.md` (written {_when(report)})"]
    if numbers.is_file():
        values = json.loads(numbers.read_text())
        undefined = sum(v is None for v in values.values())
        out[-1] += (
            f" and `results/paper/numbers.json` ({len(values)} numbers, {undefined} undefined; "
            f"written {_when(numbers)})"
        )
    out[-1] += ". Rebuild the site after a run to refresh it."
    body = report.read_text()
    body = re.sub(r"^# .*\n", "", body, count=1)
    body = re.sub(r"^(#+) ", lambda m: "#" + m.group(1) + " ", body, flags=re.M)
    return "\n".join([*out, "", body])


@dataclass
class Context:
    """What a build's placeholders need: the repository root (and config.yaml, read once)."""

    root: Path = ROOT
    config: dict[str, Any] | None = None

    def config_value(self, dotted: str) -> Any:
        if self.config is None:
            import yaml

            self.config = yaml.safe_load((self.root / "config.yaml").read_text())
        value: Any = self.config
        for part in dotted.split("."):
            if not isinstance(value, dict) or part not in value:
                raise KeyError(f"config.yaml has no key {dotted!r}")
            value = value[part]
        return value


def _relative(page: str, target: str) -> str:
    depth = len(Path(page).parent.parts)
    return "../" * depth + target


def ph_config(ctx: Context, page: str, arg: str) -> str:
    """``{{ config model.train.epochs }}``: a value of ``config.yaml`` (lists joined by commas)."""
    value = ctx.config_value(arg.strip())
    if isinstance(value, list):
        return ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
    return f"{value:,}" if isinstance(value, int) and not isinstance(value, bool) else str(value)


def _figure_site_path(path: str) -> str:
    return f"{FIGURES}/{path.removeprefix('results/')}"


def figure_files(docs_dir: Path, root: Path = ROOT) -> dict[str, Path]:
    """Site path -> file of every figure placeholder in the pages under ``docs_dir``: under ``results/`` where the
    run wrote it, else the snapshot's."""
    out = {}
    for page in sorted(docs_dir.rglob("*.md")):
        if "snapshot" in page.relative_to(docs_dir).parts:
            continue
        for m in _PLACEHOLDER.finditer(page.read_text()):
            if m.group(1) == "figure":
                path = m.group(2).partition("|")[0].strip()
                found = result_file(root, path)
                if found is not None:
                    out[_figure_site_path(path)] = found[0]
    return out


def ph_figure(ctx: Context, page: str, arg: str) -> str:
    """``{{ figure results/x.png | caption }}``: the figure (copied into the site from results/), or a note saying
    when it appears."""
    path, _, caption = (s.strip() for s in arg.partition("|"))
    if caption.startswith("@"):  # the caption the workflow's own report gives it: workflow/report/<name>.rst
        rst = (ctx.root / "workflow" / "report" / f"{caption[1:]}.rst").read_text()
        caption = " ".join(rst_to_markdown(rst).split())
    found = result_file(ctx.root, path)
    if found is not None:
        site = _figure_site_path(path)
        if found[1] is None:
            return f"![{caption}]({_relative(page, site)})\n\n*{caption}* (`{path}`, as the last run here wrote it.)"
        from imply.paper.snapshot import label

        return (
            f"![{caption}]({_relative(page, site)})\n\n*{caption}* (`{path}` from the snapshot committed with the "
            f"docs: {escape_html(label(found[1]))}; run the study to see your own.)"
        )
    return (
        f'!!! note "Figure: {caption}"\n    `{path}` appears here once it has been built '
        f"(`snakemake --cores 2 {path}`), and the site rebuilt."
    )


def ph_stage_times(ctx: Context, page: str, arg: str) -> str:
    """``{{ stage_times }}``: each stage's jobs and time in the last run, from the rules' benchmark files."""
    from imply.paper.timings import by_stage, read_benchmarks, rule_stages

    jobs = read_benchmarks(ctx.root / "results" / "benchmarks")
    snap = _snapshot(ctx.root)
    if not jobs and snap is not None and snap[1]["stage_times"]["stages"]:
        return _snapshot_stage_times(snap[1], page)
    if not jobs:
        return (
            '!!! note "Times per stage"\n    The time each stage took appears here after a run: every rule '
            "writes `results/benchmarks/<rule>/<wildcards>.tsv` (wall and CPU seconds, peak memory) and the "
            "site reads them when it is built. Until then, the [record of earlier runs](../notes/study-runs.md) "
            "gives the whole study's times on 2 cores."
        )
    out = _stage_table(by_stage(jobs, rule_stages(ctx.root)))
    newest = max(j.end for j in jobs)
    when = datetime.fromtimestamp(newest, UTC).strftime("%Y-%m-%d")
    return "\n".join(
        [
            *out,
            "",
            f"*Read from the {len(jobs)} benchmark files in `results/benchmarks/` (newest "
            f"{when}) when the site was built. Jobs of different stages run side by side on the cores, "
            "so the whole study takes less than the sum.*",
        ]
    )


def _stage_table(rows: list[dict]) -> list[str]:
    """The stage-times table's lines, from :func:`imply.paper.timings.by_stage`'s rows."""
    out = ["| stage | rules run | jobs | wall s (jobs summed) | longest job s | CPU s |", "|---|---|---|---|---|---|"]
    for row in rows:
        out.append(
            f"| {row['stage']} | {', '.join(row['rules'])} | {row['jobs']} | {row['seconds']:.0f} | "
            f"{row['longest']:.0f} | {row['cpu_seconds']:.0f} |"
        )
    return out


def _snapshot_stage_times(stamp: dict, page: str) -> str:
    """The stage-times table of the snapshot's run."""
    from imply.paper.snapshot import timing

    times = stamp["stage_times"]
    out = [snapshot_note(stamp, page), "", *_stage_table(times["stages"])]
    sittings = times.get("sittings") or []
    where = (
        " Its sittings: "
        + "; ".join(f"{s['start']} to {s['end']} UTC ({', '.join(s['stages'])})" for s in sittings)
        + "."
        if len(sittings) > 1
        else ""
    )
    return "\n".join(
        [
            *out,
            "",
            f"*{times['jobs']} jobs; the whole run took {timing(stamp)}.{where} Jobs of different stages run side by "
            "side on the cores, so the whole study takes less than the sum.*",
        ]
    )


def ph_development_time(ctx: Context, page: str, arg: str) -> str:
    """``{{ development_time }}``: how long the gap_development target took, in this checkout's last run of it or
    in the snapshot's run."""
    from imply.paper.snapshot import development_times

    times = development_times(ctx.root)
    where = "In this checkout's last run of it"
    if times is None:
        snap = _snapshot(ctx.root)
        times = None if snap is None else snap[1].get("development")
        where = f"In the snapshot's run (commit {(snap[1].get('commit') or 'unknown')[:7]})" if times else where
    if not times:
        return (
            "Its time appears here once it has run (every rule's benchmark file in `results/benchmarks/`) or a "
            "snapshot includes it."
        )
    return (
        f"{where}, its {times['jobs']} jobs took {times['wall_seconds'] / 60:.0f} min from the first to the last "
        f"({times['cpu_seconds'] / 60:.0f} CPU-min), after the default run."
    )


def ph_snapshot(ctx: Context, page: str, arg: str) -> str:
    """``{{ snapshot }}``: one sentence on the last run shown: this checkout's, or the committed snapshot's (its
    claims that hold, its wall time, its commit and machine)."""
    report = ctx.root / "results" / "paper" / "reproduction.md"
    if report.is_file():
        return (
            f"This checkout's last run wrote its [reproduction report]({_relative(page, 'status.md')}) on "
            f"{_when(report)}."
        )
    snap = _snapshot(ctx.root)
    if snap is None:
        return "The study has not run here, and no snapshot of a run is committed."
    from imply.paper.snapshot import readme_line

    return (
        f"{escape_html(readme_line(snap[1]))} Its figures and numbers are shown throughout these pages until you "
        f"run the study yourself ([reproduction status]({_relative(page, 'status.md')}))."
    )


def _fmt(value: Any, spec: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return format(value, spec)


def ph_standins(ctx: Context, page: str, arg: str) -> str:
    """``{{ standins }}``: Section 4's stand-ins through ``imply evaluate``, from ``results/evaluate/standins.json``."""
    found = result_file(ctx.root, "results/evaluate/standins.json")
    path = found[0] if found else ctx.root / "results" / "evaluate" / "standins.json"
    if not path.is_file():
        return (
            '!!! note "The stand-ins\' known answers"\n    A table of the four stand-ins (tracking r, log error, '
            "self and anchored disagreement, AUROC against the oracle, static sets) appears here once "
            "`snakemake --cores 2 results/evaluate/standins.json` has run and the site is rebuilt."
        )
    result = json.loads(path.read_text())["result"]
    out = [
        "| stand-in | tracking r | log error | self | anchored | AUROC vs oracle, self | AUROC, anchored | "
        "static sets |",
        "|---|---|---|---|---|---|---|---|",
    ]
    order = ("oracle", "jitter", "blind", "collapse")  # from the truth to the worst
    for _, s in sorted(result["standins"].items(), key=lambda kv: (order + (kv[0],)).index(kv[0])):
        out.append(
            f"| {s['model']} | {_fmt(s['track'], '.2f')} | {_fmt(s['error'], '.3f')} | "
            f"{_fmt(s['self'], '.3f')} | {_fmt(s['anchored'], '.3f')} | {_fmt(s.get('auroc_self'), '.2f')} | "
            f"{_fmt(s.get('auroc_anchored'), '.2f')} | {_fmt(s['static_share'], '.0%')} |"
        )
    ro = result["readout"]
    if found[1] is not None:
        out = [snapshot_note(found[1], page), "", *out]
    when = _when(path) if found[1] is None else f"the snapshot's run of {found[1]['date']}"
    return "\n".join(
        [
            *out,
            "",
            f"*From `results/evaluate/standins.json` ({when}): {result['n_objects']} "
            f"objects, condition {next(iter(result['standins'].values()))['condition']}, sample set 0; the "
            f"{ro['name']} readout's R² on real check clips {ro['r2_check']:.3f}, mean absolute log error "
            f"{ro['error_check']:.3f}. Every number with its interval is in "
            "`results/evaluate/standins/report.md`.*",
        ]
    )


PLACEHOLDERS: dict[str, Callable[[Context, str, str], str]] = {
    "config": ph_config,
    "figure": ph_figure,
    "stage_times": ph_stage_times,
    "development_time": ph_development_time,
    "snapshot": ph_snapshot,
    "standins": ph_standins,
}
_PLACEHOLDER = re.compile(r"\{\{\s*(\w+)\s*(.*?)\s*\}\}")


def expand(markdown: str, page: str, ctx: Context) -> str:
    """A hand-written page with its placeholders replaced (``page``: its path under docs/)."""

    def one(m: re.Match) -> str:
        name = m.group(1)
        if name not in PLACEHOLDERS:
            raise ValueError(f"{page}: unknown placeholder {{{{ {name} }}}} (known: {', '.join(PLACEHOLDERS)})")
        return PLACEHOLDERS[name](ctx, page, m.group(2))

    return _PLACEHOLDER.sub(one, markdown)


GENERATED: dict[str, Callable[[Path], str]] = {
    "reference/config.md": lambda root: config_reference(),
    "reference/cli.md": lambda root: cli_reference(),
    "reference/formats.md": lambda root: formats_reference(),
    "status.md": status_page,
}
