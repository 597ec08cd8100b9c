"""MkDocs hook: the generated pages and placeholders of the site (the work is in :mod:`imply.docs_pages`).

``on_files`` adds the reference pages and the reproduction status, rendered from the code and
``results/`` when the site is built (nothing generated is committed), and the figures that
the pages' placeholders name and ``results/`` holds; ``on_page_markdown`` fills the
hand-written pages' ``{{ ... }}`` placeholders.
"""

from __future__ import annotations

from pathlib import Path

from mkdocs.structure.files import File

from imply import docs_pages

_context = docs_pages.Context()


def on_config(config):
    global _context
    _context = docs_pages.Context(root=Path(config.config_file_path).resolve().parent)
    return config


def on_files(files, config):
    for path, render in docs_pages.GENERATED.items():
        files.append(File.generated(config, path, content=render(_context.root)))
    for site_path, source in docs_pages.figure_files(Path(config.docs_dir), _context.root).items():
        files.append(File.generated(config, site_path, abs_src_path=str(source)))
    return files


def on_page_markdown(markdown, page, config, files):
    return docs_pages.expand(markdown, page.file.src_uri, _context)
