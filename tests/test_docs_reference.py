"""The generated reference pages as a browser gets them: text that looks like HTML shown, defaults shown as values.

Docstrings and help strings write ``<stem>.json`` or ``<custom><numeric name='stroke'>`` as words;
unescaped, a browser takes them for tags and shows nothing. A help string may name a settings
default (``TableCheckConfig.cells``) that the page must show as its value. The fast tests read
the generators' Markdown (and render it with Python-Markdown); the slow ones build the site
once, as CI does, and read its HTML.
"""

from __future__ import annotations

import argparse
import re
from html.parser import HTMLParser
from pathlib import Path

import markdown
import pytest

from imply import docs_pages

ROOT = Path(__file__).resolve().parents[1]
PAGES = ("reference/cli", "reference/config", "reference/formats")

# What MkDocs, Material and the Markdown extensions emit; a tag made of a docstring's <word> is none of them.
ALLOWED_TAGS = {
    *"html head body div span a p code pre table thead tbody tr th td ul ol li em strong nav header footer".split(),
    *"main article label input script link meta title svg path button img details summary br hr form aside".split(),
    *"small sup kbd blockquote dl dt dd style template noscript i b use g symbol".split(),
    *(f"h{n}" for n in range(1, 7)),
}
CLASS_ATTRIBUTE = re.compile(r"[A-Z]\w+Config\.\w+")
DEFAULT_AS_ATTRIBUTE = re.compile(r"default: [A-Z][A-Za-z]+Config\.\w+")
# Python-Markdown's extensions as mkdocs.yml names them (those that change what HTML a page holds)
EXTENSIONS = ["admonition", "attr_list", "def_list", "tables", "toc", "pymdownx.superfences", "pymdownx.details"]


class Page(HTMLParser):
    """An HTML page read for the tests: its start tags, its text, and its tables (header -> cell texts)."""

    def __init__(self, html: str):
        super().__init__(convert_charrefs=True)
        self.tags: set[str] = set()
        self.text: list[str] = []
        self.tables: list[list[list[str]]] = []  # each a list of rows, the header row first
        self._cell: list[str] | None = None
        self._skip = 0  # inside <script> or <style>
        self.feed(html)
        self.close()

    def handle_starttag(self, tag, attrs):
        self.tags.add(tag)
        if tag in ("script", "style"):
            self._skip += 1
        elif tag == "table":
            self.tables.append([])
        elif tag == "tr" and self.tables:
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("script", "style"):
            self._skip -= 1
        elif tag in ("td", "th") and self._cell is not None and self.tables and self.tables[-1]:
            self.tables[-1][-1].append("".join(self._cell).strip())
            self._cell = None

    def handle_data(self, data):
        if self._skip:
            return
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)

    @property
    def plain(self) -> str:
        return " ".join("".join(self.text).split())

    def column(self, header: str) -> list[str]:
        """The cells of every table's column named ``header`` (header row excluded)."""
        out = []
        for table in self.tables:
            if table and header in table[0]:
                i = table[0].index(header)
                out += [row[i] for row in table[1:] if len(row) > i]
        return out


def rendered(md: str) -> Page:
    return Page(markdown.markdown(md, extensions=EXTENSIONS))


def prose(md: str) -> str:
    """Markdown without its fenced blocks and code spans (where Markdown itself escapes ``<``)."""
    md = re.sub(r"^```.*?^```", "", md, flags=re.S | re.M)
    return re.sub(r"(`+)(?!`).+?(?<!`)\1(?!`)", "", md)


# -- the helpers ---------------------------------------------------------------------------


def test_cell_escapes_html_outside_code_spans_once_and_keeps_pipes_and_backticks():
    assert docs_pages.cell("a <b> & c") == "a &lt;b&gt; &amp; c"
    assert docs_pages.cell("x `<y>` | z") == "x `<y>` \\| z"  # Markdown escapes inside the span itself
    assert docs_pages.cell("one\n  line") == "one line"
    assert docs_pages.code("a|b") == "`a\\|b`"
    assert docs_pages.code("a`b") == "``a`b``"
    assert docs_pages.code("<stage>") == "`<stage>`"
    assert docs_pages.code("") == ""
    # rendered, each shows as written: escaped once, not twice
    page = rendered(
        "| a | b |\n|---|---|\n| "
        + docs_pages.cell("<stem>.json & more")
        + " | "
        + docs_pages.code("{'a': '<b>'}")
        + " |\n"
    )
    assert page.column("a") == ["<stem>.json & more"] and page.column("b") == ["{'a': '<b>'}"]
    assert page.tags <= ALLOWED_TAGS


def test_rst_to_markdown_escapes_html_outside_code_and_literal_blocks_when_asked():
    text = """Writes ``parts/<stage>.json`` and parts/<stage>.json, a -> b & c.

    An example::

        <log>.probes.csv

    > 0 starts a line
    """
    md = docs_pages.rst_to_markdown(text, escape=True)
    assert "`parts/<stage>.json` and parts/&lt;stage&gt;.json, a -&gt; b &amp; c." in md
    assert "```text\n<log>.probes.csv\n```" in md
    assert "\n&gt; 0 starts a line" in md  # no quote, no backslash shown
    page = rendered(md)
    assert page.tags <= ALLOWED_TAGS and "blockquote" not in page.tags
    assert "and parts/<stage>.json, a -> b & c." in page.plain and "> 0 starts a line" in page.plain
    # unasked, the text is as before (a caption that becomes an attribute or a title)
    assert "parts/<stage>.json" in docs_pages.rst_to_markdown(text)


# -- the generated Markdown ------------------------------------------------------------------


@pytest.fixture(scope="module")
def generated() -> dict[str, str]:
    return {
        "reference/cli": docs_pages.cli_reference(),
        "reference/config": docs_pages.config_reference(),
        "reference/formats": docs_pages.formats_reference(),
    }


@pytest.mark.parametrize("name", PAGES)
def test_the_generated_markdown_holds_no_raw_html(generated, name):
    md = generated[name]
    raw = re.findall(r"<[A-Za-z/!][^\n>]*>?", prose(md))
    assert not raw, f"{name}: text a browser reads as HTML: {raw[:5]}"
    page = rendered(md)
    assert page.tags <= ALLOWED_TAGS, f"{name}: unknown tags {page.tags - ALLOWED_TAGS}"


def test_the_cli_markdown_shows_angle_brackets_from_help_and_descriptions(generated):
    page = rendered(generated["reference/cli"])
    assert "<custom><numeric name='stroke'>)" in page.plain
    assert "results/paper/parts/<stage>.json" in page.plain
    assert "and )." not in page.plain and "parts/.json" not in page.plain


@pytest.mark.parametrize("name", ["reference/cli", "reference/config"])
def test_no_default_in_the_generated_markdown_is_a_class_attribute(generated, name):
    md = generated[name]
    assert not DEFAULT_AS_ATTRIBUTE.search(md), DEFAULT_AS_ATTRIBUTE.findall(md)
    defaults = rendered(md).column("default")
    assert defaults, f"{name}: no default column"
    assert not [d for d in defaults if CLASS_ATTRIBUTE.search(d)]


def test_a_settings_default_a_help_string_names_is_shown_as_its_value(monkeypatch):
    from imply.table import TableCheckConfig

    def build_parser():
        parser = argparse.ArgumentParser(prog="imply", description="the command line")
        sub = parser.add_subparsers(dest="command")
        check = sub.add_parser("check", help="check a table", description="Reads <table>.npz & checks it.")
        check.add_argument("--cells", type=int, help="grid nodes to compare (default: TableCheckConfig.cells)")
        check.add_argument("--seed", type=int, help="which random nodes (default TableCheckConfig.seed)")
        check.add_argument("--from", help="a method, not a field (default: TableCheckConfig.from_dict)")
        check.add_argument("--grid", type=int, default=101, help="grid points (default %(default)d)")
        return parser

    monkeypatch.setattr("imply.cli.build_parser", build_parser)
    md = docs_pages.cli_reference()
    rows = {line.split("|")[1].split("`")[1]: line for line in md.splitlines() if line.startswith("| `--")}
    cells, seed = TableCheckConfig().cells, TableCheckConfig().seed
    assert f"| `{cells}` | grid nodes to compare (default: `{cells}`) |" in rows["--cells"]
    assert f"| `{seed}` | which random nodes (default `{seed}`) |" in rows["--seed"]
    assert "|  | a method, not a field (default: TableCheckConfig.from_dict) |" in rows["--from"]  # left as written
    assert "| `101` | grid points (default 101) |" in rows["--grid"]
    assert "Reads &lt;table&gt;.npz &amp; checks it." in md


# -- the built site ----------------------------------------------------------------------------


def built(site: Path, name: str) -> tuple[str, Page]:
    html = (site / name / "index.html").read_text()
    return html, Page(html)


@pytest.mark.slow
@pytest.mark.parametrize("name", PAGES)
def test_the_built_reference_pages_hold_only_the_tags_mkdocs_emits(docs_site, name):
    _, page = built(docs_site, name)
    assert page.tags <= ALLOWED_TAGS, f"{name}: tags made of generated text: {sorted(page.tags - ALLOWED_TAGS)}"


@pytest.mark.slow
def test_the_built_cli_reference_shows_the_angle_brackets_of_its_help(docs_site):
    html, page = built(docs_site, "reference/cli")
    assert "&lt;custom&gt;" in html and "&lt;stage&gt;" in html
    assert "<custom><numeric name='stroke'>)" in page.plain and "results/paper/parts/<stage>.json" in page.plain
    assert "and )." not in page.plain and "parts/.json" not in page.plain


@pytest.mark.slow
@pytest.mark.parametrize("name", ["reference/cli", "reference/config"])
def test_no_default_on_the_built_pages_is_a_class_attribute(docs_site, name):
    _, page = built(docs_site, name)
    assert not DEFAULT_AS_ATTRIBUTE.search(page.plain), DEFAULT_AS_ATTRIBUTE.findall(page.plain)
    defaults = page.column("default")
    assert len(defaults) > 50
    assert not [d for d in defaults if CLASS_ATTRIBUTE.search(d)]
