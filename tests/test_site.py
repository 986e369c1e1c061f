"""The documentation site (``mkdocs.yml`` over ``docs/``): every page is in the navigation, every example runs,
no page cites a document the reader does not have, the picture of the layers is the one the code draws
(``docs/layers.py``), and ``mkdocs build --strict`` passes."""

from __future__ import annotations

import doctest
import importlib.util
import pathlib
import re
import sys

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
    pictures = sorted([*(DOCS / "img").glob("*.png"), *(DOCS / "img").glob("*.svg")])
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


# --- the picture of the layers (docs/layers.py draws docs/img/layers.svg from the code) -------------------------


def _layers():
    """``docs/layers.py`` as a module (``docs`` is no package; the script needs only the standard library)."""
    spec = importlib.util.spec_from_file_location("docs_layers", DOCS / "layers.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the class is made
    spec.loader.exec_module(module)
    return module


def test_layer_picture_is_what_the_code_draws():
    # The same comparison as the site build's hook: a change of the imports or of the contracts redraws it.
    layers = _layers()
    assert layers.stale() is None, layers.stale()
    assert "img/layers.svg" in (DOCS / "architecture.md").read_text(encoding="utf-8")


def test_layer_picture_has_no_import_the_contracts_forbid():
    # lint-imports refuses them (test_architecture); the picture must agree and draw every arrow grey.
    layers = _layers()
    stack = layers.read_stack(ROOT / "pyproject.toml")
    modules, imports = layers.read_imports(ROOT / "src" / "hestore")
    for inner in [stack, *stack.inner.values()]:
        boxes, places = layers.place(inner, modules)
        assert not any(box.unlayered for box in boxes), f"{inner.container}: modules in no layer"
        found = layers.edges(boxes, places, imports)
        assert found and all(edge.down and edge.colour == layers.GREY for edge in found), inner.container


def test_layer_picture_examples_run():
    layers = _layers()
    result = doctest.testmod(layers)
    assert result.attempted and not result.failed


def test_site_build_fails_on_a_stale_layer_picture(tmp_path, monkeypatch):
    assert re.search(r"^hooks:\n\s+- docs/layers\.py$", (ROOT / "mkdocs.yml").read_text(encoding="utf-8"), re.M)
    layers = _layers()
    stale = tmp_path / "layers.svg"
    stale.write_text(layers.current().replace("errors", "mistakes"), encoding="utf-8")
    monkeypatch.setattr(layers, "PICTURE", stale)
    assert "run `python docs/layers.py` and commit it" in layers.stale()
    if _missing_tools():
        pytest.skip("the docs tools are not installed: pip install '.[docs]'")
    from mkdocs.exceptions import PluginError

    with pytest.raises(PluginError, match="python docs/layers.py"):
        layers.on_pre_build({})
    stale.unlink()
    with pytest.raises(PluginError, match="missing"):
        layers.on_pre_build({})


FAKE_CONTRACTS = """
[tool.importlinter]
root_package = "pkg"
[[tool.importlinter.contracts]]
name = "top"
type = "layers"
containers = ["pkg"]
layers = ["sub", "a | b", "c", "(d)"]
[[tool.importlinter.contracts]]
name = "the subpackage"
type = "layers"
containers = ["pkg.sub"]
layers = ["x", "y"]
[[tool.importlinter.contracts]]
name = "not a layers contract: not drawn"
type = "forbidden"
source_modules = ["pkg.c"]
forbidden_modules = ["sqlite3"]
"""
FAKE_MODULES = {
    "__init__.py": "from pkg import a\n",
    "a.py": "import pkg\nimport sqlite3\nfrom . import b  # independent of a: forbidden\n",
    "b.py": "from typing import TYPE_CHECKING\n\nif TYPE_CHECKING:\n    from pkg.c import Thing\n",
    "c.py": "def f():\n    from .a import g  # upward: forbidden\n\n\nfrom .stray import s\n",
    "d.py": "",
    "stray.py": "import pkg.c\n",
    "sub/__init__.py": "",
    "sub/x.py": "from .y import z\n",
    "sub/y.py": "from ..d import q\nfrom .. import c\n",
}


@pytest.fixture
def fake(tmp_path):
    """A package ``pkg`` with one import of each kind, some that break its contracts, and a module in no layer."""
    for name, text in FAKE_MODULES.items():
        (tmp_path / "pkg" / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / "pkg" / name).write_text(text, encoding="utf-8")
    (tmp_path / "pyproject.toml").write_text(FAKE_CONTRACTS, encoding="utf-8")
    return tmp_path


def test_layer_picture_reads_every_kind_of_import(fake):
    # Function-local, annotation-only and relative imports count; imports of the package itself and of
    # other packages do not.
    modules, imports = _layers().read_imports(fake / "pkg")
    assert modules == ["pkg.a", "pkg.b", "pkg.c", "pkg.d", "pkg.stray", "pkg.sub", "pkg.sub.x", "pkg.sub.y"]
    assert imports == {
        ("pkg.a", "pkg.b"),
        ("pkg.b", "pkg.c"),
        ("pkg.c", "pkg.a"),
        ("pkg.c", "pkg.stray"),
        ("pkg.stray", "pkg.c"),
        ("pkg.sub.x", "pkg.sub.y"),
        ("pkg.sub.y", "pkg.d"),
        ("pkg.sub.y", "pkg.c"),
    }


def test_layer_picture_flags_what_breaks_the_contracts(fake):
    layers = _layers()
    svg = layers.draw(fake / "pkg", fake / "pyproject.toml")
    assert svg == layers.draw(fake / "pkg", fake / "pyproject.toml")  # the same bytes every time

    def arrow(title):
        found = re.search(rf"<title>1 import:\n{re.escape(title)}</title><polyline [^>]*stroke=\"(#\w+)\"", svg)
        assert found, f"no arrow for {title}"
        return found.group(1)

    assert arrow("pkg.c → pkg.a") == layers.RED  # upward
    assert arrow("pkg.a → pkg.b") == layers.RED  # between independent modules of one layer
    assert arrow("pkg.c → pkg.stray") == arrow("pkg.stray → pkg.c") == layers.ORANGE
    assert arrow("pkg.b → pkg.c") == arrow("pkg.sub.y → pkg.d") == layers.GREY
    assert arrow("pkg.sub.x → pkg.sub.y") == layers.GREY  # inside the subpackage's box, by its own contract
    assert ">in no layer: stray</text>" in svg
    assert ">sub: 2 layers of its own</text>" in svg


def test_layer_picture_refuses_a_contract_it_cannot_place(fake):
    text = FAKE_CONTRACTS.replace('containers = ["pkg.sub"]', 'containers = ["pkg.elsewhere"]')
    (fake / "pyproject.toml").write_text(text, encoding="utf-8")
    with pytest.raises(ValueError, match="pkg.elsewhere"):
        _layers().draw(fake / "pkg", fake / "pyproject.toml")


def _guide_pages() -> list[str]:
    """The pages of mkdocs.yml's Guide and Contributing sections (a line ``- Title: page.md`` each)."""
    text = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    sections = re.split(r"^  - ", text.split("\nnav:\n", 1)[1], flags=re.M)
    wanted = [s for s in sections if s.startswith(("Guide:", "Contributing:"))]
    return [page for s in wanted for page in re.findall(r":\s*([\w-]+\.md)\s*$", s, re.M)]


def test_the_home_page_links_every_guide_page():
    pages = _guide_pages()
    assert {"api.md", "history.md", "repair.md", "coming-from.md", "architecture.md"} <= set(pages), pages
    home = (DOCS / "index.md").read_text(encoding="utf-8")
    missing = [page for page in pages if f"]({page})" not in home]
    assert not missing, f"docs/index.md does not link {missing}"


def test_the_readme_lists_every_command():
    from hestore.cli.parser import COMMANDS

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split("## Command line", 1)[1].split("```", 2)[1]
    listed = set(re.findall(r"^hestore (?:\[--db URL\] )?([a-z-]+)", block, re.M))
    missing = [c.name for c in COMMANDS if c.name not in listed]
    assert not missing, f"README.md's command list leaves out {missing}"
