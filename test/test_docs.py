"""The documentation site: its generated reference pages are those the code gives today, it
builds with Sphinx from scratch with every warning an error and every reference checked (a broken
link, a missing page or a page outside the toctree fails), every page of the toctree is built, and
the README's links lead to files that exist, its docs links to pages of the site."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO_ROOT

sys.path.insert(0, str(REPO_ROOT / "tools"))
import docs_reference

DOCS = REPO_ROOT / "docs"
README = REPO_ROOT / "README.md"


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site built as `make docs-check` builds it: -E (from scratch), -W --keep-going, -n."""
    out = tmp_path_factory.mktemp("site")
    done = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-q", "-E", "-W", "--keep-going", "-n", str(DOCS), str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-4000:]
    return out


def toctree_pages() -> list[str]:
    """Every page the root's toctrees name (docs/index.rst)."""
    text = (DOCS / "index.rst").read_text()
    return [line.strip() for line in text.splitlines() if line.startswith("   ") and not line.strip().startswith(":")]


def test_generated_reference_pages_are_current() -> None:
    """The reference pages and the results pages' rendered tables (docs/results/data/)."""
    pages = docs_reference.generated_pages()
    assert {path.name for path in pages} >= {*docs_reference.PAGES, "index.md", "performance.md"}
    stale = [str(path) for path, text in pages.items() if not path.is_file() or path.read_text() != text]
    assert not stale, f"stale: {stale}; run python tools/docs_reference.py"


def test_the_reference_names_every_parameter_and_command() -> None:
    from bracing_core import schema

    parameters = (DOCS / "reference" / "parameters.md").read_text()
    for param in (*schema.SHARED, *schema.SIMULATOR, *schema.CONTROLLER, *schema.CONTACT):
        assert f"`{param.name}`" in parameters
    commands = (DOCS / "reference" / "commands.md").read_text()
    for command in ("bracing-pair", "bracing-report", "bracing-view", "bracing-sweep", "bracing-optimize"):
        assert f"## {command}\n" in commands and f"usage: {command}" in commands
    assert "usage: bracing-study" in commands


def test_every_page_of_the_toctree_is_built(site: Path) -> None:
    pages = toctree_pages()
    assert len(pages) >= 20 and "getting-started" in pages and "reference/parameters" in pages
    assert (site / "index.html").is_file()
    missing = [page for page in pages if not (site / f"{page}.html").is_file()]
    assert not missing, missing
    sources = {str(p.relative_to(DOCS).with_suffix("")) for p in DOCS.rglob("*.md") if "_build" not in p.parts}
    assert sources <= set(pages), f"pages outside the toctree: {sorted(sources - set(pages))}"


def test_the_readme_links_lead_to_the_site() -> None:
    text = README.read_text()
    assert len(text.splitlines()) <= 200
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [link for link in links if "://" not in link]
    assert local, "the README links nowhere"
    missing = [link for link in local if not (REPO_ROOT / link).exists()]
    assert not missing, missing
    pages = set(toctree_pages())
    docs_pages = [link for link in local if link.startswith("docs/") and link.endswith(".md")]
    assert len(docs_pages) >= 15
    outside = [link for link in docs_pages if link.removeprefix("docs/").removesuffix(".md") not in pages]
    assert not outside, f"README links to pages the site does not build: {outside}"
