"""The report as a web page (`tavc report --html`): the committed REPORT.html is REPORT.md rendered,
and in a real browser (Debian's chromium, driven by chromedriver) it loads without an error, every
figure and link resolves, its verdict table is claims.csv's, and its contents reach every section."""

import shutil
from pathlib import Path
from urllib.parse import unquote, urlparse

import pandas as pd
import pytest

from tavc_cli.report.html import report_html

RESULTS = Path(__file__).resolve().parents[1] / "results"
PAGE = RESULTS / "REPORT.html"
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")


def test_the_committed_page_is_the_committed_report_rendered():
    assert PAGE.read_text() == report_html((RESULTS / "REPORT.md").read_text())


def test_the_page_opens_with_the_contents_then_the_verdicts():
    page = report_html("# Title\n\nIntro.\n\n| claim | verdict |\n|---|---|\n| 1 | reproduced |\n\n## One\n\n### Two\n")
    assert page.index('<nav id="contents">') < page.index("<main>") < page.index("<table>")
    assert '<a href="#one">One</a>' in page and '<a href="#two">Two</a>' in page


@pytest.fixture(scope="module")
def browser():
    if not (CHROMIUM and CHROMEDRIVER):
        pytest.skip("no chromium and chromedriver on this machine (Debian: apt-get install chromium chromium-driver; "
                    ".ci/run installs them)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--allow-file-access-from-files"):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.get(PAGE.as_uri())
    yield driver
    driver.quit()


def test_the_page_loads_without_a_console_error(browser):
    errors = [entry for entry in browser.get_log("browser") if entry["level"] == "SEVERE"]
    assert errors == []
    assert browser.title == "tavc: the reproduction report"


def test_every_figure_of_the_page_is_drawn(browser):
    images = browser.execute_script(
        "return Array.from(document.images).map(i => [i.getAttribute('src'), i.complete && i.naturalWidth > 0])")
    assert len(images) == (RESULTS / "REPORT.md").read_text().count("![")
    assert [src for src, drawn in images if not drawn] == []


def test_every_link_of_the_page_leads_somewhere(browser):
    links = browser.execute_script("return Array.from(document.links).map(a => a.href)")
    ids = set(browser.execute_script("return Array.from(document.querySelectorAll('[id]')).map(e => e.id)"))
    broken = []
    for href in links:
        url = urlparse(href)
        if url.scheme != "file":
            continue  # the page links nothing outside itself but its own files
        if url.fragment and unquote(url.path) == str(PAGE):
            broken += [href] if unquote(url.fragment) not in ids else []
        elif not Path(unquote(url.path)).exists():
            broken.append(href)
    assert broken == []


def test_the_verdict_table_is_claims_csv(browser):
    rows = browser.execute_script(
        "return Array.from(document.querySelector('main table').rows).slice(1)"
        ".map(r => Array.from(r.cells).map(c => c.textContent.trim()))")
    claims = pd.read_csv(RESULTS / "claims.csv")
    words = {"reproduced": "reproduced", "not_reproduced": "not reproduced", "inconclusive": "inconclusive"}
    assert [(int(r[0]), r[2]) for r in rows] == [
        (int(c.claim_id), words.get(c.verdict, c.verdict)) for c in claims.itertuples()]


def test_the_contents_reach_every_section(browser):
    targets = browser.execute_script(
        "return Array.from(document.querySelectorAll('#contents a')).map(a => a.getAttribute('href').slice(1))")
    sections = browser.execute_script(
        "return Array.from(document.querySelectorAll('main h2[id], main h3[id]')).map(h => h.id)")
    assert targets == sections and len(sections) > 20


def test_a_page_the_report_wrote_is_kept_in_step_by_a_report_without_html(tmp_path):
    from typer.testing import CliRunner

    from tavc_cli.cli import app
    from tavc_cli.config import load_config, settings
    from tavc_cli.pipeline import run_experiment

    run_experiment(settings(load_config(["experiment=initial_distribution", "scale=smoke", "trials=1",
                                         "baseline_trials=1", f"output_dir={tmp_path / 'initial_distribution'}"])))
    assert CliRunner().invoke(app, ["report", str(tmp_path)]).exit_code == 0
    assert not (tmp_path / "REPORT.html").exists()  # no page unless asked for
    assert CliRunner().invoke(app, ["report", str(tmp_path), "--html"]).exit_code == 0
    (tmp_path / "REPORT.html").write_text("an old page")  # as if REPORT.md had changed since
    # an edit of tavc's own page is tavc's to replace: the next report, without --html, rewrites it
    assert CliRunner().invoke(app, ["report", str(tmp_path)]).exit_code == 0
    assert (tmp_path / "REPORT.html").read_text() == report_html((tmp_path / "REPORT.md").read_text())
