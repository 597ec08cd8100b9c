"""MkDocs hook: the generated pages and placeholders of the site (the work is in :mod:`imply.docs_pages`).

``on_files`` adds the reference pages and the reproduction status, rendered from the code and
``results/`` when the site is built (nothing generated is committed), the Python API page
(:func:`imply.docs_api.api_reference`), the changelog (``CHANGELOG.md`` at the repository
root, outside ``docs/``), and the figures that the pages' placeholders name and ``results/``
holds; ``on_page_markdown`` fills the hand-written pages' ``{{ ... }}`` placeholders.
"""

from __future__ import annotations

import re
from pathlib import Path

from mkdocs.structure.files import File

from imply import docs_pages
from imply.docs_api import api_reference

_context = docs_pages.Context()


def changelog_page(root: Path) -> str:
    """``CHANGELOG.md`` of the repository as the site's ``changelog.md``.

    The site's page sits at the top of ``docs/``, so a link into ``docs/`` loses that prefix.
    """
    text = (root / "CHANGELOG.md").read_text(encoding="utf-8")
    return re.sub(r"\]\(docs/", "](", text)


def on_config(config):
    global _context
    _context = docs_pages.Context(root=Path(config.config_file_path).resolve().parent)
    return config


def on_files(files, config):
    for path, render in docs_pages.GENERATED.items():
        files.append(File.generated(config, path, content=render(_context.root)))
    files.append(File.generated(config, "reference/python-api.md", content=api_reference()))
    files.append(File.generated(config, "changelog.md", content=changelog_page(_context.root)))
    for site_path, source in docs_pages.figure_files(Path(config.docs_dir), _context.root).items():
        files.append(File.generated(config, site_path, abs_src_path=str(source)))
    return files


def on_page_markdown(markdown, page, config, files):
    return docs_pages.expand(markdown, page.file.src_uri, _context)
