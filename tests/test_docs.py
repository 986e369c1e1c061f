"""The examples in the docstrings, and in the pages of ``docs/`` listed in ``RUN_PAGES``, run and print what they
say."""

from __future__ import annotations

import doctest
import importlib
import pathlib
import pkgutil
import re

import pytest

import hestore

from meshes import require_shared_meshes

# walk_packages, not iter_modules: subpackages' modules (hestore.io.*) have examples too.
MODULES = sorted(
    ["hestore"]
    + [
        m.name
        for m in pkgutil.walk_packages(hestore.__path__, prefix="hestore.")
        if m.name.rsplit(".", 1)[-1] != "__main__"
    ]
)


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # examples that touch ./hestore.db stay in the sandbox
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"


DOCS = pathlib.Path(__file__).resolve().parents[1] / "docs"
#: Pages whose ```python blocks run, in order, as one script; a block marked ```python no-run is skipped (it
#: shows what needs something the tests do not have).
RUN_PAGES = ("properties.md", "editing.md", "repair.md", "history.md", "render.md", "coming-from.md")
#: Pages whose examples import the shared meshes by name run in their folder (they only read there).
IN_MESHES = ("repair.md",)


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, re.M | re.S)


@pytest.mark.parametrize("page", RUN_PAGES)
def test_page_examples_run(page, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(require_shared_meshes() if page in IN_MESHES else tmp_path)
    blocks = python_blocks((DOCS / page).read_text(encoding="utf-8"))
    assert blocks, f"docs/{page} has no python example"
    namespace: dict = {"__name__": f"docs_{page}"}
    for k, block in enumerate(blocks):
        exec(compile(block, f"docs/{page} block {k + 1}", "exec"), namespace)
    # Every printed line is the one its comment announces: on the print's own line, or on the line after it.
    printed = capsys.readouterr().out.splitlines()
    announced = []
    for block in blocks:
        lines = block.splitlines()
        for i, line in enumerate(lines):
            if not line.startswith("print("):
                continue
            m = re.match(r"print\(.*\)\s+# (.*)$", line)
            follow = lines[i + 1] if i + 1 < len(lines) else ""
            announced.append(m.group(1) if m else follow.removeprefix("# ") if follow.startswith("# ") else None)
    assert len(printed) == len(announced), (printed, announced)
    for got, want in zip(printed, announced):
        assert want is not None and (got == want or want.startswith((got + ": ", got + " "))), (got, want)
