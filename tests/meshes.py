"""Where the shared outside test meshes are, and the corpus: each imported once per backend.

The meshes (real files from public repositories, described in their
``MANIFEST.md``) live beside the repository, in ``shared/meshes``, and are
never copied into it. `shared_meshes` finds the folder; tests that need it
call `require_shared_meshes`, which skips them where the folder is missing —
except under ``CI=true``, where a missing folder fails them: CI must never
pass without them.

`Corpus` holds the files imported into one store of a backend, each the
first time a test asks for it: the ``corpus`` fixture of ``conftest.py``
makes one per backend for the whole test session (for each worker of a
parallel run), so that the large files are imported once rather than by
every test that reads them. Tests read its meshes and never change them
(the fixture checks, and deletes what a test added); a test that edits one
edits a `Corpus.copy`. A test of a corpus file is parametrized by
``corpus_file`` through `corpus_files`, whose test ids name the file
(`corpus_id`): a parallel run keeps a file's tests on one worker.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import os
import pathlib
import re

import pytest

import hestore
from hestore.errors import InvalidInputError, TopologyError

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


# -- the corpus ----------------------------------------------------------------------------------

#: The suffixes of the files in the shared meshes folder that hestore reads itself.
SUFFIXES = (".off", ".obj", ".ply")

#: What `corpus_files` gives where there is no shared meshes folder: one test each, which then skips (or fails).
MISSING = "no-shared-meshes"


def shared_files() -> list[pathlib.Path]:
    """Every OFF, OBJ and PLY file of the shared meshes folder, sorted (skips or fails as `require_shared_meshes`)."""
    folder = require_shared_meshes()
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in SUFFIXES)


def corpus_names(max_bytes: int | None = None, exclude=(), only=None) -> list[str]:
    """The names of `shared_files` (at most ``max_bytes`` long, not in ``exclude``, in ``only`` if given).

    Read when the tests are collected. Where the folder is missing, `MISSING`
    alone: the test made for it skips (or fails under CI) when it asks the
    corpus for it.
    """
    folder = shared_meshes()
    if folder is None:
        return [MISSING]
    return [p.name for p in sorted(folder.iterdir()) if p.suffix.lower() in SUFFIXES and p.name not in exclude
            and (only is None or p.name in only) and (max_bytes is None or p.stat().st_size <= max_bytes)]


def corpus_id(name: str) -> str:
    """The test id of a test's corpus file, e.g. ``corpus:cow.obj``: a parallel run keeps a file's tests together.

    `corpus_group` reads it back from the test's node id, on the process
    that hands tests to the workers (``conftest``).
    """
    return f"corpus:{name}"


#: A corpus file in a node id: ``corpus:`` and the name, up to the end of the parameters or the next one.
_CORPUS_ID = re.compile(r"corpus:(.+?\.(?:off|obj|ply)|" + re.escape(MISSING) + r")(?=[\]-])")
_BACKEND_ID = re.compile(r"[\[-](sqlite|postgresql)(?=[\]-])")


def corpus_group(nodeid: str) -> str | None:
    """What goes to one worker of a parallel run with the test of this node id (None: the test alone).

    The tests of a corpus file: they share its imports and its reference.
    A file bigger than `SLOW_BYTES` is split by backend, which is all its
    tests share (it has no reference), so that its slow tests spread over
    the workers.

    >>> corpus_group("tests/test_x.py::test_y[sqlite-corpus:cube-minimal.ply]")
    'cube-minimal.ply'
    >>> corpus_group("tests/test_x.py::test_y[corpus:igea-subdiv1.ply-postgresql]"), corpus_group("t.py::test")
    ('igea-subdiv1.ply on postgresql', None)
    """
    found = _CORPUS_ID.search(nodeid)
    if found is None:
        return None
    name = found.group(1)
    backend = _BACKEND_ID.search(nodeid[nodeid.find("["):])
    return f"{name} on {backend.group(1)}" if backend and name in _slow_files() else name


@functools.cache
def _slow_files() -> frozenset[str]:
    folder = shared_meshes()
    return frozenset(p.name for p in folder.iterdir() if p.stat().st_size > SLOW_BYTES) if folder else frozenset()


#: Files bigger than this (bytes) make their tests slow: they are started first.
SLOW_BYTES = 1_000_000


def corpus_files(max_bytes: int | None = None, exclude=(), only=None, backend: str | None = None) -> list:
    """`corpus_names` as parameters of ``corpus_file`` (or of ``backend, corpus_file``), each with its `corpus_id`.

    The tests of a file bigger than `SLOW_BYTES` are marked ``slow``, those
    of ``backend="postgresql"`` ``postgresql``.
    """
    folder = shared_meshes()
    params = []
    for name in corpus_names(max_bytes, exclude, only):
        big = folder is not None and (folder / name).stat().st_size > SLOW_BYTES
        marks = [pytest.mark.slow] * big + [pytest.mark.postgresql] * (backend == "postgresql")
        if backend is None:
            params.append(pytest.param(name, id=corpus_id(name), marks=marks))
        else:
            params.append(pytest.param(backend, name, id=f"{backend}-{corpus_id(name)}", marks=marks))
    return params


@dataclasses.dataclass(frozen=True)
class Imported:
    """One shared file as the corpus imported it.

    ``refusal`` is what ``import_file(path, name)`` (``on_error="raise"``)
    raised, or None when the file imported whole; ``report`` is the import
    that is stored: that one, or after a refusal ``on_error="skip"``.
    ``revision`` is the mesh's revision after it, which no test may change.
    """

    path: pathlib.Path
    refusal: TopologyError | InvalidInputError | None
    report: hestore.ImportReport
    revision: int

    @property
    def mesh(self) -> hestore.Mesh:
        return self.report.mesh


class Corpus:
    """The shared files imported into one store, each on first use, under its file's stem.

    Parameters
    ----------
    url : str
        A database at the schema's head that only the corpus uses.
    """

    def __init__(self, url: str):
        self.store = hestore.open(url)
        self._imported: dict[str, Imported] = {}
        self._copies = itertools.count()

    def imported(self, name: str) -> Imported:
        """The file ``name`` of the shared meshes folder, imported as described in `Imported`."""
        if name not in self._imported:
            path = require_shared_meshes() / name
            try:
                refusal, report = None, self.store.import_file(path, path.stem)
            except (TopologyError, InvalidInputError) as exc:
                refusal, report = exc, self.store.import_file(path, path.stem, on_error="skip")
            self._imported[name] = Imported(path, refusal, report, report.mesh.revision)
        return self._imported[name]

    def mesh(self, name: str) -> hestore.Mesh:
        """The stored mesh of the file ``name``, to read only."""
        return self.imported(name).mesh

    def copy(self, name: str) -> hestore.Mesh:
        """A copy of the mesh of the file ``name`` (`hestore.Store.copy_mesh`), the test's own to edit."""
        return self.store.copy_mesh(self.imported(name).mesh.name, f"copy{next(self._copies)}")

    def release(self) -> list[str]:
        """After a test: delete every mesh it added (copies, duals); returns the files whose mesh it changed."""
        ours = {imported.mesh.name: imported for imported in self._imported.values()}
        names = set(self.store.meshes())
        for name in names - ours.keys():
            self.store.delete_mesh(name)
        return [imported.path.name for name, imported in ours.items()
                if name not in names or self.store.mesh(name).revision != imported.revision]

    def close(self) -> None:
        self.store.close()
