"""The examples in the docstrings run and print what they say."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import hestore

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
