"""Where the shared outside test meshes are.

The meshes (real files from public repositories, described in their
``MANIFEST.md``) live beside the repository, in ``shared/meshes``, and are
never copied into it. `shared_meshes` finds the folder; tests that need it
call `require_shared_meshes`, which skips them where the folder is missing —
except under ``CI=true``, where a missing folder fails them: CI must never
pass without them.
"""

from __future__ import annotations

import os
import pathlib

import pytest

REPOSITORY = pathlib.Path(__file__).resolve().parents[1]
DEVELOPMENT_LAYOUT = pathlib.Path("/work/shared/meshes")
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


def _is_meshes(folder: pathlib.Path) -> bool:
    return (folder / "MANIFEST.md").is_file()


def shared_meshes() -> pathlib.Path | None:
    """The shared meshes folder, or None where there is none.

    In order: ``$HESTORE_TEST_MESHES``; the first ``<ancestor>/shared/meshes``
    holding a ``MANIFEST.md``, over the ancestors of the repository root, then
    of the working directory; the development machines' ``/work/shared/meshes``.
    """
    env = os.environ.get("HESTORE_TEST_MESHES")
    if env:
        folder = pathlib.Path(env)
        return folder if folder.is_dir() else None
    for base in (REPOSITORY, pathlib.Path.cwd().resolve()):
        for ancestor in base.parents:
            if _is_meshes(ancestor / "shared" / "meshes"):
                return ancestor / "shared" / "meshes"
    return DEVELOPMENT_LAYOUT if _is_meshes(DEVELOPMENT_LAYOUT) else None


def require_shared_meshes() -> pathlib.Path:
    """The shared meshes folder; skips the calling test where there is none (fails under CI)."""
    folder = shared_meshes()
    if folder is not None:
        return folder
    env = os.environ.get("HESTORE_TEST_MESHES")
    if env:
        reason = f"HESTORE_TEST_MESHES={env} is not a folder"
    else:
        reason = (
            "no shared/meshes folder with a MANIFEST.md beside the repository or the working directory, "
            f"nor at {DEVELOPMENT_LAYOUT}; set HESTORE_TEST_MESHES"
        )
    if IN_CI:
        pytest.fail(f"CI=true but the shared test meshes are missing: {reason}", pytrace=False)
    pytest.skip(f"shared test meshes not found: {reason}")
