"""REPORT.md rendered as one web page, REPORT.html beside it: the same text, tables and figures
(one source, two renderings), with a table of contents, readable offline from ``file://``.

The figures are the report's own files, linked relatively (``figures/...``,
``converged/figures/...``), so the page works wherever the results folder is, and the docs
site copies the folder's page and figures under ``site/report/`` (`make docs`).
"""

from __future__ import annotations

import html
from pathlib import Path

from tavc_cli.io import write_text_atomic
from tavc_cli.readers import read_text

HTML_FILE = "REPORT.html"
REPORT_LIMIT = 64 * 2**20  # REPORT.md read bounded, as every file a command reads

_CSS = """
body { margin: 0; font: 15px/1.5 system-ui, sans-serif; color: #222; }
nav { position: fixed; top: 0; bottom: 0; left: 0; width: 18rem; overflow-y: auto; padding: 1rem;
      background: #f6f6f4; border-right: 1px solid #ddd; font-size: 13px; }
nav ul { padding-left: 1rem; margin: 0.2rem 0; }
main { margin-left: 20rem; padding: 1rem 2rem 4rem; max-width: 78rem; }
table { border-collapse: collapse; margin: 0.8rem 0; font-size: 13px; }
th, td { border: 1px solid #ccc; padding: 0.25rem 0.5rem; vertical-align: top; }
th { background: #eee; }
img { max-width: 100%; height: auto; border: 1px solid #eee; }
code { background: #f2f2f2; padding: 0 0.2rem; }
h1, h2, h3 { scroll-margin-top: 1rem; }
@media (max-width: 60rem) { nav { position: static; width: auto; } main { margin-left: 0; } }
"""


def report_html(markdown_text: str, title: str = "tavc: the reproduction report") -> str:
    """The page for a report's Markdown: its sections (headings of levels 2 and 3) in a table of
    contents beside it."""
    import markdown  # deferred: loaded only where a page is asked for

    renderer = markdown.Markdown(extensions=["tables", "toc", "fenced_code"],
                                 extension_configs={"toc": {"toc_depth": "2-3"}})
    body = renderer.convert(markdown_text)
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
            f'<nav id="contents"><strong>Contents</strong>\n{renderer.toc}</nav>\n'
            f"<main>\n{body}\n</main>\n</body>\n</html>\n")


def write_report_html(results_dir: Path) -> Path:
    """REPORT.html beside results_dir's REPORT.md, rendered from it."""
    path = Path(results_dir) / HTML_FILE
    write_text_atomic(path, report_html(read_text(Path(results_dir) / "REPORT.md", REPORT_LIMIT)))
    return path
