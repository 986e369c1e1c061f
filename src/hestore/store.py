"""The store: a database of named meshes, and its transactions.

This module owns the mesh catalogue — creating, finding, listing and deleting
meshes by name — and `open`, the entry point. Everything that touches the
connection (transactions, locks, units of work, flushing, threads, error
translation) is the `hestore.session.Session` the store holds as
`Store.session`; the store only says what to do in each scope.

A store belongs to the thread that opened it: open one per thread or process.
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from typing import Iterator

import sqlalchemy as sa

from hestore import bulk, interop, schema, urls, values
from hestore.errors import InvalidInputError, MeshExistsError, MeshNotFoundError, shown
from hestore.journal import created_changes
from hestore.mesh import Mesh
from hestore.session import Session

__all__ = ["open", "Store", "DEFAULT_URL"]

#: Where `open` goes when given no URL and ``$HESTORE_URL`` is unset.
DEFAULT_URL = urls.DEFAULT_URL


def open(url: str | sa.engine.URL | None = None, *, busy_timeout: float = 5.0) -> "Store":
    """Open (and if new, create) a hestore database.

    Parameters
    ----------
    url : str or sqlalchemy.engine.URL, optional
        A SQLAlchemy URL: ``"sqlite:///path.db"``, ``"sqlite://"`` (in
        memory), ``"postgresql+psycopg://user@host/db"`` (``postgresql://``
        means the same); a bare path is exactly that SQLite file. Default:
        ``$HESTORE_URL``, else ``./hestore.db``.
    busy_timeout : float
        Seconds to wait for another writer's lock before `StoreBusyError`
        (PostgreSQL waits at most about 24.8 days, its longest lock timeout).

    Returns
    -------
    Store

    Raises
    ------
    InvalidInputError
        Not a URL or a path, a database hestore does not support
        (`hestore.urls`), or a ``busy_timeout`` that is not a finite number
        of seconds ≥ 0.
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
    """
    return Store(url, busy_timeout=busy_timeout)


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
    session : hestore.session.Session
        The connection, transactions and units of work: the door every
        module of hestore reads and writes through.
    """

    def __init__(self, url: str | sa.engine.URL | None = None, *, busy_timeout: float = 5.0) -> None:
        seconds = values.check_real(busy_timeout, "busy_timeout (seconds)")
        if not 0 <= seconds < math.inf:
            raise InvalidInputError(f"busy_timeout must be a number of seconds ≥ 0, not {shown(busy_timeout)}")
        self.url = urls.resolve(url)
        self.busy_timeout = seconds
        self.session = Session(self.url, busy_timeout=self.busy_timeout)

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
        m = schema.meshes
        with self.session.scope() as conn:
            if conn.execute(sa.select(m.c.id).where(m.c.name == name)).first() is not None:
                raise MeshExistsError(f"a mesh named {name!r} already exists")
            try:
                mesh_id = conn.execute(
                    m.insert()
                    .values(
                        name=name,
                        allow_loops=allow_loops,
                        allow_multi_edges=allow_multi_edges,
                        revision=0,
                        next_vertex=0,
                        next_edge=0,
                        next_polygon=0,
                        next_property=0,
                        history=history,
                    )
                    .returning(m.c.id)
                ).scalar_one()
            except sa.exc.IntegrityError:
                # Another connection took the name between the check and the insert.
                raise MeshExistsError(f"a mesh named {name!r} already exists") from None
            ref = self.session.new_ref(mesh_id, name)
        return Mesh(self, ref, allow_loops, allow_multi_edges)

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
        m = schema.meshes
        with self.session.reading() as conn:
            row = conn.execute(
                sa.select(m.c.id, m.c.allow_loops, m.c.allow_multi_edges).where(m.c.name == name)
            ).first()
        if row is None:
            known = self.meshes()
            hint = f"; meshes here: {', '.join(known[:10])}" if known else "; the store has no meshes"
            raise MeshNotFoundError(f"no mesh named {name!r} in {self.session.shown_url}{hint}")
        return Mesh(self, self.session.ref(row.id, name), bool(row.allow_loops), bool(row.allow_multi_edges))

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
        m = schema.meshes
        with self.session.reading() as conn:
            return list(conn.execute(sa.select(m.c.name).order_by(m.c.name)).scalars())

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
        with self.session.editing(mesh.ref) as uow:
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
        m = schema.meshes
        with self.session.scope() as conn:
            self.session.lock(mesh.ref)
            if conn.execute(sa.select(m.c.id).where(m.c.name == new_name)).first() is not None:
                raise MeshExistsError(f"a mesh named {new_name!r} already exists")
            try:
                conn.execute(m.update().where(m.c.id == mesh.id).values(name=new_name))
            except sa.exc.IntegrityError:
                raise MeshExistsError(f"a mesh named {new_name!r} already exists") from None
            self.session.renamed(mesh.ref, new_name)
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
        m = schema.meshes
        with self.session.scope() as conn:
            # Locked: the tables are read by several statements, and must not change between them.
            self.session.lock(source.ref)
            row = conn.execute(sa.select(m).where(m.c.id == source.id)).one()
            at = row.revision if revision is None else revision
            view = self.session.view(source.ref, at)  # checks that the revision is kept
            copy = self.create_mesh(
                new_name, allow_loops=row.allow_loops, allow_multi_edges=row.allow_multi_edges, history=row.history
            )
            conn.execute(
                m.update()
                .where(m.c.id == copy.id)
                .values(
                    revision=1,
                    next_vertex=row.next_vertex,
                    next_edge=row.next_edge,
                    next_polygon=row.next_polygon,
                    next_property=row.next_property,
                )
            )
            for table in schema.VERSIONED:
                self.session.copy_rows(view, copy.ref, table)
            counts = copy.counts()
            self.session.add_revision(
                copy.ref, 1, f"copy of {source.name!r} at revision {at}",
                created_changes(counts.vertices, counts.halfedges, counts.edges, counts.polygons),
            )
        return copy

    # -- bulk ----------------------------------------------------------------------

    def import_arrays(self, name: str, positions, polygons, *, on_error: str = "raise", **options) -> bulk.ImportReport:
        """Store a polygon soup as a new mesh; see `hestore.bulk.import_arrays`.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> store.import_arrays("tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).polygons
        1
        """
        return bulk.import_arrays(self, _checked_name(name), positions, polygons, on_error=on_error, **options)

    def import_file(self, path, name: str | None = None, *, on_error: str = "raise", **options) -> bulk.ImportReport:
        """Import an OFF, OBJ or PLY file as a new mesh (`hestore.bulk.import_file`), or STL, VTK, VTU through meshio.

        The meshio formats (`hestore.interop.read_meshio_file`) take the
        same options; their polygon cells become polygons.
        """
        path = urls.check_path(path)
        if name is not None:
            name = _checked_name(name)
        if path.lower().endswith(interop.MESHIO_EXTENSIONS):
            return interop.read_meshio_file(self, path, name, on_error=on_error, **options)
        return bulk.import_file(self, path, name, on_error=on_error, **options)

    def import_trimesh(self, name: str, tm, **options) -> bulk.ImportReport:
        """Store a ``trimesh.Trimesh`` as a new mesh; see `hestore.interop.import_trimesh`."""
        return interop.import_trimesh(self, _checked_name(name), tm, **options)

    def import_meshio(self, name: str, m, **options) -> bulk.ImportReport:
        """Store a ``meshio.Mesh`` of polygon cells as a new mesh; see `hestore.interop.import_meshio`."""
        return interop.import_meshio(self, _checked_name(name), m, **options)
