"""The house rules a tool can keep: the module layers and the linter.

The layers are an import-linter contract in ``pyproject.toml``
(``[tool.importlinter]``): from the command line down through the catalogue,
the mesh facade, the algorithms and the session to storage and the errors,
no module imports one above it — function-local imports included — so no
import cycle can come back unnoticed; and no module above the session
imports SQLAlchemy (a ``forbidden`` contract). Ruff's rules are in
``[tool.ruff]``.
"""

from __future__ import annotations

import ast
import importlib
import pathlib
import subprocess
import sys
import tomllib

from importlinter.cli import lint_imports

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_import_layers_are_kept(capsys):
    status = lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True)
    out = capsys.readouterr().out
    assert status == 0, out
    assert "0 broken" in out


def test_the_layer_contract_sees_function_local_imports(tmp_path, capsys):
    # The contract only protects the layers if it reads imports inside functions too.
    config = tmp_path / "contract.toml"
    config.write_text(
        '[tool.importlinter]\nroot_package = "hestore"\n'
        '[[tool.importlinter.contracts]]\nname = "errors below mesh"\ntype = "forbidden"\n'
        'source_modules = ["hestore.mesh"]\nforbidden_modules = ["hestore.graphs"]\n'
    )
    # hestore.mesh imports hestore.graphs only inside Mesh.to_networkx.
    assert lint_imports(config_filename=str(config), no_cache=True) == 1
    assert "hestore.mesh -> hestore.graphs" in capsys.readouterr().out


def test_every_module_above_the_session_is_kept_from_sqlalchemy():
    # The forbidden contract lists its modules: it must list every one the layers put above the session.
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    layers = next(c for c in contracts if c.get("containers") == ["hestore"])["layers"]
    above = {f"hestore.{m.strip()}" for layer in layers[: layers.index("_session")] for m in layer.split("|")}
    [sql] = [c for c in contracts if c["type"] == "forbidden"]
    assert sql["forbidden_modules"] == ["sqlalchemy"]
    assert set(sql["source_modules"]) == above


def test_ruff_finds_nothing():
    done = subprocess.run(
        [sys.executable, "-m", "ruff", "check", "--no-cache", str(ROOT)],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert done.returncode == 0, done.stdout + done.stderr


def test_public_names_are_exported_once():
    import hestore

    assert len(hestore.__all__) == len(set(hestore.__all__))
    assert all(hasattr(hestore, name) for name in hestore.__all__)


def test_public_names_are_loaded_from_where_the_source_says():
    # The package loads its names on first use (hestore._HOMES); tools that read the source see the imports
    # under TYPE_CHECKING. The two, and __all__, must name the same names in the same modules.
    import hestore

    tree = ast.parse((ROOT / "src" / "hestore" / "__init__.py").read_text())
    [guarded] = [node for node in tree.body if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING"]
    imported = {(node.module, alias.name) for node in guarded.body for alias in node.names}
    loaded = {(module, name) for module, names in hestore._HOMES.items() for name in names}
    assert imported == loaded
    assert sorted(hestore.__all__) == sorted(name for _, name in loaded)
    for module, name in loaded:
        assert getattr(hestore, name) is getattr(importlib.import_module(module), name)


def test_import_hestore_loads_nothing_else():
    # What lets the command line's entry point (hestore.__main__) run, and catch Ctrl-C, before the heavy imports.
    done = subprocess.run(
        [sys.executable, "-c", "import sys, hestore, hestore.__main__; print(sorted(sys.modules))"],
        capture_output=True, text=True, check=True,
    )
    loaded = ast.literal_eval(done.stdout)
    assert [m for m in loaded if m.startswith("hestore")] == ["hestore", "hestore.__main__"]
    assert not [m for m in loaded if m.partition(".")[0] in ("sqlalchemy", "numpy", "typing", "dataclasses")]
