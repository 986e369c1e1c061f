"""The documentation site (``mkdocs.yml`` over ``docs/``): every page is in the navigation, every example runs,
no page cites a document the reader does not have, and ``mkdocs build --strict`` passes."""

from __future__ import annotations

import importlib.util
import pathlib
import re

import pytest

from test_docs import RUN_PAGES

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: Pictures committed to the repository stay below this size (as ``docs/pictures.py`` checks when it makes them).
PICTURE_LIMIT = 150_000
#: Mentions of documents outside the site: the specification's sections, issue numbers.
INTERNAL = re.compile(r"\bSPEC\b|(?i:\bissue\s*#)")


def nav_pages() -> list[str]:
    """The pages of ``mkdocs.yml``'s ``nav``, as paths below ``docs/``, in order.

    Read from the text, not with a YAML parser: the nav is a list of ``- title: page.md`` or ``- page.md`` lines.
    """
    text = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    nav = text.split("\nnav:\n", 1)[1]
    return re.findall(r"^\s+- (?:[^\n]*?: )?([\w./-]+\.md)\s*$", nav, re.M)


def site_pages() -> list[str]:
    return sorted(p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md"))


def test_nav_pages_exist_and_every_page_is_in_the_nav():
    nav = nav_pages()
    assert nav, "mkdocs.yml has no nav"
    assert len(nav) == len(set(nav)), f"pages twice in the nav: {sorted(p for p in nav if nav.count(p) > 1)}"
    missing = [p for p in nav if not (DOCS / p).is_file()]
    assert not missing, f"in mkdocs.yml's nav but not in docs/: {missing}"
    left_out = sorted(set(site_pages()) - set(nav))
    assert not left_out, f"in docs/ but not in mkdocs.yml's nav: {left_out}"


def test_coming_from_examples_run_with_the_others():
    # test_docs.test_page_examples_run runs them, and checks what they print.
    assert "coming-from.md" in RUN_PAGES


@pytest.mark.parametrize("page", site_pages())
def test_no_page_cites_internal_documents(page):
    text = (DOCS / page).read_text(encoding="utf-8")
    found = [line for line in text.splitlines() if INTERNAL.search(line)]
    assert not found, f"docs/{page} cites documents the reader does not have: {found}"


def test_pictures_are_small_and_shown():
    pages = "\n".join((DOCS / p).read_text(encoding="utf-8") for p in site_pages())
    pictures = sorted((DOCS / "img").glob("*.png"))
    assert pictures
    for picture in pictures:
        size = picture.stat().st_size
        assert size < PICTURE_LIMIT, f"{picture.name} is {size:,} bytes: regenerate it smaller (docs/pictures.py)"
        assert f"img/{picture.name}" in pages, f"docs/img/{picture.name} is on no page"


def _missing_tools() -> list[str]:
    missing = []
    for name in ("mkdocs", "mkdocstrings", "mkdocstrings_handlers.python", "material"):
        try:
            found = importlib.util.find_spec(name) is not None
        except ModuleNotFoundError:  # the parent package is missing
            found = False
        if not found:
            missing.append(name)
    return missing


def test_site_builds_strict(tmp_path, monkeypatch):
    missing = _missing_tools()
    if missing:
        pytest.skip(f"the docs tools are not installed ({', '.join(missing)}): pip install '.[docs]'")
    from mkdocs.commands.build import build
    from mkdocs.config import load_config

    monkeypatch.setenv("NO_MKDOCS_2_WARNING", "1")  # mkdocs-material's notice about its successor
    site = tmp_path / "site"
    config = load_config(str(ROOT / "mkdocs.yml"), site_dir=str(site), strict=True)
    build(config)  # strict: any warning (a broken link or anchor, a docstring mkdocstrings cannot read) aborts
    assert (site / "index.html").is_file()
    assert (site / "reference" / "mesh" / "index.html").is_file()
    # The API reference shows docstrings, which are not pages: they must not cite internal documents either.
    cited = [
        p.relative_to(site).as_posix()
        for p in site.rglob("*.html")
        if INTERNAL.search(re.sub(r"<[^>]+>", "", p.read_text(encoding="utf-8")))
    ]
    assert not cited, f"built pages citing documents the reader does not have: {cited}"
