"""The README and the documentation site: the site builds, every link resolves, the README stays
short and leads with the two commands, its verdicts are the committed claims' verdicts, and the
license and citation files are there and well formed."""

import re
import subprocess
import sys
import unicodedata
from pathlib import Path

import pandas as pd
import pytest
import yaml

from tavc_cli import __version__
from tavc_cli.analysis.claims import CLAIMS
from tests.helpers import REPO

README = REPO / "README.md"
DOCS = REPO / "docs"
PAGES = [README, *sorted(DOCS.glob("*.md"))]
# the verdict columns of the README's table (and docs/claims.md's), and the claims files they report
HORIZONS = {"at the chapter's durations": REPO / "results" / "claims.csv",
            "at 40x": REPO / "results" / "converged" / "claims.csv"}


def test_the_site_builds_in_strict_mode(tmp_path):
    # strict: a broken link or anchor between pages, or a page missing from the files, fails the build
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=REPO, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / "site" / "index.html").is_file()
    nav = yaml.safe_load((REPO / "mkdocs.yml").read_text())["nav"]
    listed = {page for entry in nav for page in entry.values()}
    assert listed == {p.name for p in DOCS.glob("*.md")}, "every page in docs/ is in mkdocs.yml's nav, and only those"


def _prose(text: str) -> str:
    """The text without fenced code blocks and inline code, where brackets are not links."""
    text = re.sub(r"^(```|~~~).*?^\1", "", text, flags=re.S | re.M)
    return re.sub(r"`[^`\n]*`", "", text)


def _links(text: str) -> list[str]:
    return re.findall(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", _prose(text))


def _slugs(path: Path) -> set[str]:
    """The anchors of a page's headings, as GitHub and as MkDocs make them."""
    slugs = set()
    for heading in re.findall(r"^#{1,6}\s+(.+?)\s*#*\s*$", _prose(path.read_text()), flags=re.M):
        heading = heading.replace("`", "").replace("*", "")
        github = re.sub(r"[^\w\- ]", "", heading.lower()).replace(" ", "-")
        ascii_ = unicodedata.normalize("NFKD", heading).encode("ascii", "ignore").decode()
        mkdocs = re.sub(r"[-\s]+", "-", re.sub(r"[^\w\s-]", "", ascii_).strip().lower())
        slugs |= {github, mkdocs}
    return slugs


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_every_relative_link_and_image_resolves(page):
    broken = []
    for target in _links(page.read_text()):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("<"):
            continue  # a web address or a placeholder, not a file here
        file_part, _, anchor = target.partition("#")
        path = (page.parent / file_part).resolve() if file_part else page
        if not path.exists():
            broken.append(f"{target}: no such file")
        elif anchor and path.suffix == ".md" and anchor not in _slugs(path):
            broken.append(f"{target}: no heading with that anchor")
    assert not broken, f"{page.name}: " + "; ".join(broken)


def test_the_readme_is_short_and_leads_with_the_two_commands():
    lines = README.read_text().splitlines()
    assert len(lines) < 220
    top = "\n".join(lines[:25])
    assert "make reproduce-all" in top and "make test" in top


def test_the_quickstart_is_one_block_of_tavc_commands():
    text = README.read_text()
    match = re.search(r"<!-- quickstart -->\s*```sh\n(.*?)```\s*<!-- /quickstart -->", text, re.S)
    assert match, "the quickstart block is missing or not one ```sh block between its markers"
    commands = [line.split("#")[0].strip() for line in match.group(1).splitlines() if line.strip()]
    assert commands and all(c.startswith("tavc ") for c in commands)


def _verdict_tables(text: str) -> list[dict[int, dict[str, str]]]:
    """Every Markdown table with the verdict columns: claim id -> column header -> cell."""
    tables, rows = [], []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            rows.append([cell.strip() for cell in line.strip().strip("|").split("|")])
            continue
        if rows and all(h in rows[0] for h in ("claim", *HORIZONS)):
            header = rows[0]
            tables.append({int(r[0]): dict(zip(header, r, strict=True)) for r in rows[2:]})
        rows = []
    return tables


def _expected() -> dict[str, dict[int, str]]:
    """Per verdict column, each claim's verdict as the claims file gives it, in the README's words."""
    return {column: {int(r.claim_id): r.verdict.replace("_", " ") for r in pd.read_csv(path).itertuples()}
            for column, path in HORIZONS.items()}


@pytest.mark.parametrize("page", [README, DOCS / "claims.md"], ids=lambda p: p.name)
def test_the_verdict_table_is_the_committed_claims(page):
    tables = _verdict_tables(page.read_text())
    assert len(tables) == 1, f"{page.name}: expected one table of verdicts, found {len(tables)}"
    table = tables[0]
    expected = _expected()
    for column, verdicts in expected.items():
        assert set(table) == set(verdicts), f"{page.name}: the table's claims are not the claims file's"
        shown = {claim: row[column].replace("*", "").strip() for claim, row in table.items()}
        assert shown == verdicts, f"{page.name}, column {column!r}: not the verdicts of {HORIZONS[column]}"
    assert {claim: row["experiment"] for claim, row in table.items()} == {c: CLAIMS[c][0] for c in table}


def test_the_headline_counts_the_committed_verdicts():
    headline = re.search(r"Reproduced: (\d+) of (\d+) claims at the chapter's durations, (\d+) of (\d+) at 40 times",
                         README.read_text())
    assert headline, "the README's headline count is missing"
    counts = [(sum(v == "reproduced" for v in verdicts.values()), len(verdicts)) for verdicts in _expected().values()]
    assert [int(g) for g in headline.groups()] == [n for pair in counts for n in pair]


def test_license_and_citation():
    assert "the tavc authors" in (REPO / "LICENSE").read_text()
    cff = yaml.safe_load((REPO / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0"
    assert cff["title"] and cff["authors"] and cff["message"]
    assert str(cff["version"]) == __version__
    chapter = [r for r in cff["references"] if "improving task allocation" in r["title"]]
    assert len(chapter) == 1
    ref = chapter[0]
    assert [a["family-names"] for a in ref["authors"]] == ["Dahl", "Matarić", "Sukhatme"]
    assert ref["collection-title"].startswith("Complex Engineered Systems")
    assert ref["year"] == 2006 and ref["editors"]
