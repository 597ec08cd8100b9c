"""The Python API page (imply.docs_api): what a model author implements and calls, read from the code; the site's hook
adds it and the changelog."""

from __future__ import annotations

import dataclasses
import inspect
import re
from pathlib import Path

import pytest

from imply import docs_api

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def page() -> str:
    return docs_api.api_reference()


def prose(markdown: str) -> str:
    """``markdown`` without its fenced code blocks and inline code spans."""
    text = re.sub(r"^\s*```.*?^\s*```", "", markdown, flags=re.S | re.M)
    return re.sub(r"(`+)(.+?)(?<!`)\1(?!`)", "", text)


def test_the_page_names_the_request_its_fields_and_the_entry_points(page):
    from imply.evaluate import RolloutRequest, evaluate, write_report

    for name in ("RolloutRequest", "WorldModel", "evaluate", "write_report", "Scorer"):
        assert f"### `{name}`" in page, name
    for f in dataclasses.fields(RolloutRequest):
        shown = f.type.replace("|", "\\|")  # a pipe in a table cell is escaped
        assert f"| `{f.name}` | `{shown}` |" in page, f.name
    # signatures as the code has them: every parameter of the entry points, in the code block under its heading
    for func in (evaluate, write_report):
        block = page.split(f"### `{func.__name__}`", 1)[1].split("```", 2)[1]
        for name in inspect.signature(func).parameters:
            assert f"{name}:" in block, (func.__name__, name)
    assert "`from imply.evaluate import evaluate`" in page
    for kind in ("frames", "latents", "displacements"):
        assert f"| `{kind}` |" in page  # the output kinds table


def test_the_page_has_no_raw_angle_bracket_outside_code(page):
    text = prose(page)
    assert "<" not in text and ">" not in text
    assert "&amp;lt;" not in page and "&amp;gt;" not in page  # escaped once
    assert "-&gt; float" in page  # a docstring's arrow, kept visible


def test_escape_html_keeps_code_and_escapes_the_rest_once():
    md = "a < b & c `x<y>&` d\n```python\nf(a) -> b < c\n```\n\\> quoted"
    out = docs_api.escape_html(md)
    assert out == "a &lt; b &amp; c `x<y>&` d\n```python\nf(a) -> b < c\n```\n&gt; quoted"
    assert docs_api.escape_html(out) == out


def test_hanging_indents_of_name_text_paragraphs_join_their_paragraph():
    doc = "Title.\n\nalpha: the first\n  continued. beta: the second.\n\n``term``\n    a definition"
    md = docs_api.docstring(type("X", (), {"__doc__": doc}))
    assert "alpha: the first continued. beta: the second." in md
    assert "`term`\n:   a definition" in md


def test_signatures_break_long_parameter_lists_and_keep_markers():
    def f(a: int, /, b: str = "x", *, c: float | None = None) -> list[int]: ...

    assert docs_api.signature("f", f) == "f(a: int, /, b: str = 'x', *, c: float | None = None) -> list[int]"
    docs_api_line = docs_api.LINE
    try:
        docs_api.LINE = 20
        assert docs_api.signature("f", f).splitlines() == [
            "f(",
            "    a: int,",
            "    /,",
            "    b: str = 'x',",
            "    *,",
            "    c: float | None = None,",
            ") -> list[int]",
        ]
    finally:
        docs_api.LINE = docs_api_line


def test_the_hook_adds_the_api_page_and_the_changelog_and_the_nav_lists_them():
    from mkdocs.config import load_config
    from mkdocs.structure.files import Files

    # the hook as mkdocs loads and calls it (mkdocs.yml's hooks), without building the site (test_docs does)
    config = load_config(str(ROOT / "mkdocs.yml"))
    config = config.plugins.on_config(config)
    files = config.plugins.on_files(Files([]), config=config)
    by_uri = {f.src_uri: f for f in files}
    assert "# Python API" in by_uri["reference/python-api.md"].content_string
    assert by_uri["changelog.md"].content_string == (ROOT / "CHANGELOG.md").read_text(encoding="utf-8").replace(
        "](docs/", "]("
    )
    nav = str(config["nav"])
    for page in ("reference/python-api.md", "how-to/troubleshooting.md", "changelog.md"):
        assert page in nav, page
    assert config["site_url"]
