"""The store: a database of named meshes, and its transactions.

This module owns the mesh catalogue — creating, finding, listing, renaming,
copying and deleting meshes by name, and storing imports (it decides the
name, creates the mesh and hands `hestore.bulk` the mesh to fill) — and
`open`, the entry point. Its SQL is `hestore._queries.catalogue`'s. Everything that
touches the connection (transactions, locks, units of work, flushing,
threads, error translation) is the `hestore._session.Session` the store
holds as `Store.session`; the store only says what to do in each scope.

A store belongs to the thread that opened it: open one per thread or process.
"""

from __future__ import annotations

import dataclasses
from contextlib import contextmanager
from typing import Iterator

from hestore import bulk, interop, schema, urls
from hestore import _drivers as drivers
from hestore import _values as values
from hestore import io as mesh_io
from hestore.errors import InvalidInputError, MeshExistsError, MeshNotFoundError
from hestore._journal import created_changes
from hestore.mesh import Mesh
from hestore._queries import catalogue
from hestore._session import Session, identity

__all__ = ["open", "Store", "DEFAULT_URL", "DEFAULT_BUSY_TIMEOUT"]

#: Where `open` goes when given no URL and ``$HESTORE_URL`` is unset.
DEFAULT_URL = urls.DEFAULT_URL

#: Seconds `open`'s store waits for another writer's lock, unless told otherwise.
DEFAULT_BUSY_TIMEOUT = drivers.DEFAULT_BUSY_TIMEOUT


def open(
    url: str | urls.URL | None = None, *, busy_timeout: float = DEFAULT_BUSY_TIMEOUT, create: bool = True
) -> "Store":
    """Open (and if new and ``create``, create) a hestore database.

    Parameters
    ----------
    url : str or sqlalchemy.engine.URL, optional
        A SQLAlchemy URL: ``"sqlite:///path.db"``, ``"sqlite://"`` (in
        memory), ``"postgresql+psycopg://user@host/db"`` (``postgresql://``
        means the same); a bare path is exactly that SQLite file. Default:
        ``$HESTORE_URL``, else ``./hestore.db``.
    busy_timeout : float
        Seconds to wait for another writer's lock before `StoreBusyError`
        (PostgreSQL waits at most about 24.8 days, its longest lock timeout):
        every write waits that long for another connection's transaction to
        end. Default `DEFAULT_BUSY_TIMEOUT`, 5 seconds.
    create : bool
        Whether to make the database if there is none: a SQLite file that
        does not exist is created, a database without hestore's tables
        (an empty file, a new PostgreSQL database, an in-memory one) gets
        them, at the current schema. With ``create=False`` those are
        `StoreNotFoundError` and nothing is created: for code that only
        means to read what is there (the command line's commands but
        ``import``, ``demo`` and ``db upgrade``).

    Returns
    -------
    Store

    Raises
    ------
    InvalidInputError
        Not a URL or a path, a database hestore does not support
        (`hestore.urls`), or a ``busy_timeout`` that is not a finite number
        of seconds ≥ 0.
    StoreNotFoundError
        With ``create=False``: the SQLite file does not exist, or the
        database has no hestore tables.
    StoreError
        The database cannot be opened or used: not a database, unreachable,
        tables of another application in the way, driver not installed.
    SchemaVersionError
        The database was made by another version of hestore; run
        ``hestore db upgrade``.

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> store.meshes()
    []
    >>> store.close()
    >>> hestore.open("no/such/meshes.db", create=False)
    Traceback (most recent call last):
    ...
    hestore.errors.StoreNotFoundError: no database at sqlite:///no/such/meshes.db: the file ... does not exist
    """
    return Store(url, busy_timeout=busy_timeout, create=create)


def _checked_name(name: object) -> str:
    """``name`` if it can be a mesh name, else `InvalidInputError` saying why."""
    return values.check_name(name, "a mesh name")


class Store:
    """A hestore database: named meshes and the transactions that edit them.

    Use `open` to make one. A store is a context manager that closes itself.

    Attributes
    ----------
    url : sqlalchemy.engine.URL
        The database.
    busy_timeout : float
        Seconds to wait for another writer's lock.
    session : hestore._session.Session
        The connection, transactions and units of work: the door every
        module of hestore reads and writes through.

    Notes
    -----
    A store reads like a mapping of names to meshes, as a networkx graph
    reads like one of nodes to neighbours: ``name in store``,
    ``store[name]`` (`mesh`; a missing name is `MeshNotFoundError`, a
    `KeyError`), ``len(store)`` and ``for name in store`` (`meshes`, sorted).
    It is not written through that mapping: `create_mesh`, `delete_mesh`
    and `rename_mesh` say what they do.

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> _ = store.create_mesh("cube"); _ = store.create_mesh("cow")
    >>> "cow" in store, "horse" in store, len(store), list(store)
    (True, False, 2, ['cow', 'cube'])
    >>> store["cow"].name
    'cow'
    >>> store["horse"]
    Traceback (most recent call last):
    ...
    hestore.errors.MeshNotFoundError: no mesh named 'horse' in sqlite://; meshes here: cow, cube
    """

    def __init__(
        self, url: str | urls.URL | None = None, *, busy_timeout: float = DEFAULT_BUSY_TIMEOUT, create: bool = True
    ) -> None:
        seconds = values.check_seconds(busy_timeout, "busy_timeout")
        create = values.check_flag(create, "create")
        self.url = urls.resolve(url)
        self.busy_timeout = seconds
        self.session = Session(self.url, busy_timeout=self.busy_timeout, create=create)

    def __repr__(self) -> str:
        return f"Store({self.session.shown_url!r})"

    def close(self) -> None:
        """Roll back anything uncommitted and close the connection."""
        self.session.close()

    def __enter__(self) -> "Store":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- transactions -----------------------------------------------------------

    @property
    def in_transaction(self) -> bool:
        """Whether a ``with store.transaction():`` block is open."""
        return self.session.in_transaction

    @contextmanager
    def transaction(self, message: str | None = None) -> Iterator["Store"]:
        """A block whose edits commit together or not at all.

        ``message`` is kept with the revision each changed mesh gets when
        the block commits (`Mesh.history`).

        An exception leaving the block rolls everything in it back; nested
        blocks are savepoints. Reads inside see the block's own edits; other
        connections see them only after the outermost block commits. A mesh
        created in a block that is rolled back is gone, and so are its
        handles (they raise `MeshNotFoundError`).

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> mesh = store.create_mesh("m")
        >>> with store.transaction():
        ...     a, b = mesh.add_vertex(), mesh.add_vertex()
        ...     e = mesh.add_edge(a, b)
        >>> mesh.counts().edges, mesh.revision
        (1, 1)
        >>> try:
        ...     with store.transaction():
        ...         mesh.remove_edge(e)
        ...         raise RuntimeError("changed my mind")
        ... except RuntimeError:
        ...     pass
        >>> mesh.counts().edges, mesh.revision
        (1, 1)
        """
        if message is not None:
            # Checked here, not when the block commits: a message SQL cannot hold would lose every edit.
            values.check_text(message, "a transaction's message")
        with self.session.transaction(message):
            yield self

    # -- the mesh catalogue -------------------------------------------------------

    def create_mesh(
        self, name: str, *, allow_loops: bool = True, allow_multi_edges: bool = True, history: bool = True
    ) -> Mesh:
        """Create an empty mesh.

        Parameters
        ----------
        name : str
            Unique within the store: at most 255 characters of Unicode text,
            not blank, no control characters.
        allow_loops, allow_multi_edges : bool
            Whether self-loop edges and parallel edges may be added.
        history : bool
            Whether every revision is kept. Without, nothing
            is recorded: `Mesh.history` is empty and only the current
            revision can be read.

        Returns
        -------
        Mesh

        Raises
        ------
        MeshExistsError
            A mesh of that name exists.
        InvalidInputError
            The name cannot be a mesh name.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> store.create_mesh("part", allow_loops=False)
        Mesh('part')
        """
        name = _checked_name(name)
        allow_loops = values.check_flag(allow_loops, "allow_loops")
        allow_multi_edges = values.check_flag(allow_multi_edges, "allow_multi_edges")
        history = values.check_flag(history, "history")
        with self.session.scope() as db:
            mesh_id = catalogue.create(db, name, allow_loops, allow_multi_edges, history)
            ref = self.session.new_ref(mesh_id, name, allow_loops, allow_multi_edges)
        return Mesh(self, ref)

    def mesh(self, name: str) -> Mesh:
        """The mesh called ``name``.

        Raises
        ------
        MeshNotFoundError
            No mesh has that name.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> _ = store.create_mesh("part")
        >>> store.mesh("part").name
        'part'
        """
        name = _checked_name(name)
        with self.session.querying() as db:
            entry = catalogue.find(db, name)
        if entry is None:
            known = self.meshes()
            hint = f"; meshes here: {', '.join(known[:10])}" if known else "; the store has no meshes"
            raise MeshNotFoundError(f"no mesh named {name!r} in {self.session.shown_url}{hint}")
        return Mesh(self, self.session.ref(entry.id, name, entry.allow_loops, entry.allow_multi_edges))

    def __contains__(self, name: object) -> bool:
        """Whether a mesh is called ``name`` (False for anything that cannot be a mesh name)."""
        try:
            name = _checked_name(name)
        except InvalidInputError:
            return False
        with self.session.querying() as db:
            return catalogue.find(db, name) is not None

    def __getitem__(self, name: str) -> Mesh:
        """The mesh called ``name``: `mesh`."""
        return self.mesh(name)

    def __len__(self) -> int:
        """How many meshes the store holds."""
        return len(self.meshes())

    def __iter__(self) -> Iterator[str]:
        """The meshes' names, sorted, as they were when iteration began: `meshes`."""
        return iter(self.meshes())

    def meshes(self) -> list[str]:
        """Names of all meshes, sorted.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> _ = store.create_mesh("b"); _ = store.create_mesh("a")
        >>> store.meshes()
        ['a', 'b']
        """
        with self.session.querying() as db:
            return catalogue.names(db)

    def delete_mesh(self, name: str) -> None:
        """Delete the mesh called ``name`` and all its elements.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> _ = store.create_mesh("tmp")
        >>> store.delete_mesh("tmp"); store.meshes()
        []
        """
        mesh = self.mesh(name)
        with self.session.editing(identity(mesh)) as uow:
            uow.drop()

    def rename_mesh(self, name: str, new_name: str) -> Mesh:
        """Give the mesh called ``name`` a new name; its handles follow.

        An edit of the catalogue like any other: inside a block it is undone
        with the block (handles then show the old name again).

        Raises
        ------
        MeshNotFoundError
            No mesh has that name.
        MeshExistsError
            A mesh is called ``new_name`` already.
        InvalidInputError
            ``new_name`` cannot be a mesh name.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> part = store.create_mesh("part")
        >>> store.rename_mesh("part", "bracket"), part.name, store.meshes()
        (Mesh('bracket'), 'bracket', ['bracket'])
        """
        new_name = _checked_name(new_name)
        mesh = self.mesh(name)
        if new_name == mesh.name:
            return mesh
        with self.session.scope() as db:
            self.session.lock(identity(mesh))
            catalogue.rename(db, mesh.id, new_name)
            self.session.renamed(identity(mesh), new_name)
        return mesh

    def copy_mesh(self, name: str, new_name: str, revision: int | None = None) -> Mesh:
        """A new mesh with the same ids and content as the mesh called ``name``.

        Elements, positions, properties and their values, the policy and the
        id counters are copied in one set-based statement per table; the copy
        is independent afterwards (its ids go on from the source's, so no id
        the source ever used is handed out by the copy), and its revision is 1.

        Parameters
        ----------
        name, new_name : str
            The source and the copy.
        revision : int, optional
            The source's revision to copy (default: its current one): any
            kept revision, so a copy branches the mesh at that point.

        Raises
        ------
        MeshNotFoundError
            No mesh is called ``name``.
        MeshExistsError
            A mesh is called ``new_name`` already.
        RevisionNotFoundError
            ``revision`` was never made or is no longer kept.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> mesh = store.import_arrays("tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
        >>> copy = store.copy_mesh("tri", "tri2")
        >>> copy.counts() == mesh.counts(), copy.revision, copy.vertex(2).position
        (True, 1, (0.0, 1.0, 0.0))
        """
        new_name = _checked_name(new_name)
        source = self.mesh(name)
        if revision is not None:
            revision = values.check_revision(revision)
        with self.session.scope() as db:
            # Locked: the tables are read by several statements, and must not change between them.
            self.session.lock(identity(source))
            row = catalogue.row(db, source.id)
            at = row.revision if revision is None else revision
            self.session.view(identity(source), at)  # checks that the revision is kept
            copy = self.create_mesh(
                new_name, allow_loops=row.allow_loops, allow_multi_edges=row.allow_multi_edges, history=row.history
            )
            catalogue.copy_counters(db, copy.id, row)
            for table in schema.VERSIONED:
                catalogue.copy_rows(db, source.id, None if at == row.revision else at, copy.id, table)
            counts = copy.counts()
            catalogue.add_revision(
                db, copy.id, 1, f"copy of {source.name!r} at revision {at}",
                created_changes(counts.vertices, counts.halfedges, counts.edges, counts.polygons),
            )
        return copy

    # -- bulk ----------------------------------------------------------------------

    def import_arrays(self, name: str, positions, polygons, *, on_error: str = "raise", **options) -> bulk.ImportReport:
        """Store a polygon soup as a new mesh, built set-based: one transaction, the whole mesh or nothing.

        The result is the topology that `Mesh.add_polygon` would give, called
        on the polygons one by one in order (up to the order of free gaps
        around a vertex where several fans meet): vertex ``i`` is
        ``positions[i]``, polygon ids follow input order among the polygons
        kept, and vertices no polygon uses are kept as isolated vertices.
        Every check is made, and every repair decided, before anything is
        written (`hestore.bulk.build_arrays`).

        Parameters
        ----------
        name : str
            The new mesh's name.
        positions : array_like, shape (V, 3) or (V, 2)
            Finite coordinates.
        polygons : array_like, shape (F, k), or sequence of sequences of int
            Corners of each polygon, counter-clockwise, as row indices of
            ``positions``.
        on_error : {"raise", "skip", "split"}
            What to do with a polygon the structure cannot take
            (`hestore.bulk.ImportOptions`).
        **options
            The other `hestore.bulk.ImportOptions`: ``allow_loops``,
            ``allow_multi_edges``, ``progress``, ``replace``, ``orient``,
            ``history``.

        Returns
        -------
        ImportReport

        Raises
        ------
        InvalidInputError, HalfEdgeNotFreeError, NonManifoldError, PolicyError
            With ``on_error="raise"``, for the first bad polygon; the error's
            ``skipped`` attribute is its `SkippedPolygon`.
        NonOrientableError
            With ``orient=True``, a component that cannot be oriented.
        MeshExistsError
            A mesh of that name exists (and ``replace`` is not set).

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> square = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
        >>> report = store.import_arrays("square", square, [[0, 1, 2], [0, 2, 3]])
        >>> report.polygons, report.edges, report.mesh.check()
        (2, 5, [])
        >>> report = store.import_arrays("bad", square, [[0, 1, 2], [0, 1, 3]], on_error="skip")
        >>> report.polygons, report.skipped[0].index
        (1, 1)
        >>> report = store.import_arrays("kept", square, [[0, 1, 2], [0, 1, 3]], on_error="split")
        >>> report.polygons, report.vertices, report.split
        (2, 6, {0: [4], 1: [5]})
        """
        options = bulk.ImportOptions(on_error=on_error, **options)
        name = self._new_name(name, options)
        return self._store(name, bulk.build_arrays(positions, polygons, options), options)

    def import_file(self, path, name: str | None = None, *, on_error: str = "raise", **options) -> bulk.ImportReport:
        """Import an OFF, OBJ or PLY file (ASCII or binary) as a new mesh, or an STL, VTK or VTU file through meshio.

        The file's vertex and polygon order are kept, vertices are never
        welded by position and polygons are never triangulated; see
        `import_arrays` for what is built and how bad polygons are handled
        (each `SkippedPolygon` carries its file line for ASCII files). A
        PLY file's vertex and face properties and an OBJ file's corner
        ``uv``/``normal`` become properties of the new mesh
        (`hestore.bulk.build_file`). The meshio formats
        (`hestore.interop.read_meshio_file`) take the same options, but for
        ``progress``, which they do not report; their polygon cells become
        polygons.

        Parameters
        ----------
        path : str or os.PathLike
            The file; its format comes from its extension.
        name : str, optional
            The new mesh's name; by default the file name without extension.
        on_error, **options
            As for `import_arrays`.

        Raises
        ------
        InvalidInputError
            The file is malformed (bad header, non-numeric or non-finite
            values, truncated): the message names the file and line. The file
            cannot be read (missing, a folder, no permission: ``"cannot read
            {path}: {reason}"``), the path cannot be one, or an option is
            malformed. Nothing is stored.

        Examples
        --------
        >>> import hestore, tempfile, pathlib
        >>> folder = pathlib.Path(tempfile.mkdtemp())
        >>> _ = (folder / "tri.off").write_text("OFF\\n3 1 0\\n0 0 0\\n1 0 0\\n0 1 0\\n3 0 1 2\\n")
        >>> store = hestore.open("sqlite://")
        >>> report = store.import_file(folder / "tri.off")
        >>> report.mesh.name, report.vertices, report.polygons
        ('tri', 3, 1)
        """
        path = urls.check_path(path)
        options = bulk.ImportOptions(on_error=on_error, **options)
        if path.lower().endswith(interop.MESHIO_EXTENSIONS):
            name = self._new_name(bulk.name_of(path) if name is None else name, options)
            silent = dataclasses.replace(options, progress=None)
            return self._store(name, bulk.build_arrays(*interop.read_meshio_file(path), silent), options)
        mesh_io.format_of(path)  # an unknown extension is refused before the name is looked at
        name = self._new_name(bulk.name_of(path) if name is None else name, options)
        return self._store(name, bulk.build_file(path, options), options)

    def import_trimesh(self, name: str, tm, **options) -> bulk.ImportReport:
        """Store a ``trimesh.Trimesh`` as a new mesh, vertex ``i`` and face ``j`` in its order; see `import_arrays`.

        Examples
        --------
        >>> import hestore, trimesh
        >>> store = hestore.open("sqlite://")
        >>> report = store.import_trimesh("box", trimesh.creation.box())
        >>> report.polygons, report.mesh.stats().is_closed
        (12, True)
        """
        return self.import_arrays(name, *interop.trimesh_soup(tm), **options)

    def import_meshio(self, name: str, m, **options) -> bulk.ImportReport:
        """Store a ``meshio.Mesh`` of polygon cells as a new mesh; see `hestore.interop.meshio_soup`, `import_arrays`.

        Examples
        --------
        >>> import hestore, meshio
        >>> store = hestore.open("sqlite://")
        >>> m = meshio.Mesh([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [("triangle", [[0, 1, 2]])])
        >>> store.import_meshio("t", m).polygons
        1
        """
        return self.import_arrays(name, *interop.meshio_soup(m), **options)

    def _new_name(self, name: object, options: bulk.ImportOptions) -> str:
        """The name of a mesh an import makes, checked before anything is read or built.

        Taken already is `MeshExistsError`, unless the import replaces it.
        """
        name = _checked_name(name)
        if not options.replace and name in self.meshes():
            raise MeshExistsError(f"a mesh named {name!r} already exists; choose another name")
        return name

    def _store(self, name: str, built: bulk.BuiltImport, options: bulk.ImportOptions) -> bulk.ImportReport:
        """Create the mesh and write a built import into it, in one step; with ``replace`` the old mesh goes in it."""
        session = self.session
        outer = not session.in_transaction
        with session.scope():
            if options.replace and name in self.meshes():
                self.delete_mesh(name)
            mesh = self.create_mesh(
                name, allow_loops=options.allow_loops, allow_multi_edges=options.allow_multi_edges,
                history=options.history,
            )
            bulk.write(identity(mesh), built, options.progress)
        if outer:
            # Fresh statistics, so that the planner knows how large the tables just became.
            session.analyze(bulk.WRITTEN)
        return built.report(mesh)
