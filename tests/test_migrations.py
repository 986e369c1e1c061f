"""Schema migrations: the Alembic revisions build exactly `hestore.schema`.

Runs on SQLite and PostgreSQL (the ``db_url`` fixture). Where these tests fail
after a schema change, ``docs/migrations.md`` says what is missing.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext

import hestore
from hestore import migrate, schema

VERSIONED = {
    "vertices", "halfedges", "edges", "polygons", "properties", "property_reals", "property_integers", "property_texts",
}
HISTORY = {f"{name}_history" for name in VERSIONED}
TABLES = {"meshes", "revisions", *VERSIONED, *HISTORY}
ELEMENT_TABLES = TABLES - {"meshes"}
#: The tables each revision adds.
ADDED = {"0001": {"meshes", "vertices", "halfedges", "edges", "polygons"}, "0002": set(),
         "0003": {"properties", "property_reals", "property_integers", "property_texts"},
         "0004": {"revisions", *HISTORY}, "0005": set()}
INDEXES = {"ix_halfedges_origin", "ix_halfedges_polygon"}


@pytest.fixture
def engine(db_url):
    engine = sa.create_engine(db_url, poolclass=sa.pool.NullPool)
    yield engine
    engine.dispose()


def _differences(conn: sa.Connection) -> list:
    context = MigrationContext.configure(conn, opts={"compare_type": migrate.compare_type})
    return compare_metadata(context, schema.metadata)


def _index_names(conn: sa.Connection) -> set[str]:
    return {ix["name"] for ix in sa.inspect(conn).get_indexes("halfedges")}


def test_head_revision_is_schema_revision():
    assert migrate.head_revision() == schema.SCHEMA_REVISION


def test_history_is_one_line_of_numbered_revisions():
    # Numbered 0001, 0002, ... in order, one file each, named after the id.
    revisions = migrate.revisions()
    assert revisions == [f"{n:04d}" for n in range(1, len(revisions) + 1)]
    assert revisions[-1] == migrate.head_revision()
    location = Path(migrate.script_location())
    assert (location / "env.py").is_file()
    files = sorted(p.name for p in (location / "versions").glob("*.py"))
    assert [name[:4] for name in files] == revisions


def test_upgrade_in_steps_then_open(db_url, engine):
    with engine.connect() as conn:
        assert migrate.current_revision(conn) is None
        migrate.upgrade(conn, "0001")
        assert migrate.current_revision(conn) == "0001"
        assert set(sa.inspect(conn).get_table_names()) - {"alembic_version"} == ADDED["0001"]
        assert _index_names(conn) == set()

        migrate.upgrade(conn)
        assert migrate.current_revision(conn) == migrate.head_revision()
        assert _index_names(conn) == INDEXES

    with hestore.open(db_url) as store:
        mesh = store.create_mesh("m")
        a, b, c = (mesh.add_vertex((x, y, 0.0)) for x, y in [(0, 0), (1, 0), (0, 1)])
        mesh.add_polygon([a, b, c])
        assert mesh.counts().polygons == 1
        assert mesh.check() == []


def test_head_matches_schema(engine, backend):
    with engine.connect() as conn:
        migrate.upgrade(conn)
        assert _differences(conn) == []
        if backend == "sqlite":
            sql = dict(
                conn.execute(sa.text("SELECT name, sql FROM sqlite_master WHERE type = 'table'")).all()
            )
            for table in ELEMENT_TABLES:
                assert "WITHOUT ROWID" in sql[table], table
            assert "WITHOUT ROWID" not in sql["meshes"]


def test_comparison_notices_a_missing_revision(engine):
    # Guards the test above: at 0001 the indexes of 0002 are missing, and
    # compare_metadata must say so.
    with engine.connect() as conn:
        migrate.upgrade(conn, "0001")
        added = {
            diff[1].name for diff in _differences(conn) if diff[0] == "add_index" and diff[1].table.name == "halfedges"
        }
    assert added == INDEXES


def test_new_database_is_created_at_head(db_url, engine):
    hestore.open(db_url).close()
    with engine.connect() as conn:
        assert migrate.current_revision(conn) == migrate.head_revision()
        assert _differences(conn) == []


def test_open_refuses_an_older_database(db_url, engine):
    with engine.connect() as conn:
        migrate.upgrade(conn, "0001")
    with pytest.raises(hestore.SchemaVersionError, match="hestore db upgrade"):
        hestore.open(db_url)
    with engine.connect() as conn:
        assert migrate.current_revision(conn) == "0001"  # refused, not migrated


def test_downgrade_to_base_and_back(engine):
    with engine.connect() as conn:
        migrate.upgrade(conn)
        migrate.downgrade(conn, "base")
        assert migrate.current_revision(conn) is None
        assert not TABLES & set(sa.inspect(conn).get_table_names())

        migrate.upgrade(conn)
        assert migrate.current_revision(conn) == migrate.head_revision()
        assert _differences(conn) == []


def test_environment_opens_its_own_connection(db_url, engine):
    # The URL path of env.py, as the `alembic` command line uses it; the
    # PostgreSQL URL carries %-escapes that must survive the ini-style config.
    command.upgrade(migrate.alembic_config(url=db_url), "head")
    with engine.connect() as conn:
        assert migrate.current_revision(conn) == migrate.head_revision()


def test_environment_falls_back_to_hestore_url(tmp_path, monkeypatch):
    url = f"sqlite:///{tmp_path / 'env.db'}"
    monkeypatch.setenv("HESTORE_URL", url)
    command.upgrade(migrate.alembic_config(), "0001")
    with sa.create_engine(url).connect() as conn:
        assert migrate.current_revision(conn) == "0001"


def test_current_revision_rejects_a_branched_version_table(engine):
    with engine.connect() as conn:
        migrate.upgrade(conn)
        conn.execute(sa.text("INSERT INTO alembic_version (version_num) VALUES ('0001')"))
        conn.commit()
        with pytest.raises(hestore.SchemaVersionError, match="several schema revisions"):
            migrate.current_revision(conn)


def _store_triangle_by_hand(conn: sa.Connection) -> None:
    """A one-triangle mesh written with the SQL of the database's revision (no hestore involved).

    From 0004 on, the rows say they were written by revision 1, which is kept, as 0004 makes them.
    """
    conn.execute(sa.text(
        "INSERT INTO meshes (name, allow_loops, allow_multi_edges, revision, next_vertex, next_edge, next_polygon) "
        "VALUES ('old', true, true, 1, 3, 3, 1)"
    ))
    mesh_id = conn.execute(sa.text("SELECT id FROM meshes WHERE name = 'old'")).scalar_one()
    # Half-edges 0, 2, 4 run 0→1→2→0 around polygon 0; 1, 3, 5 are their free twins,
    # and each vertex's half-edge is its free outgoing one.
    for v, (x, h) in enumerate([(0.0, 5), (1.0, 1), (0.5, 3)]):
        conn.execute(sa.text(
            f"INSERT INTO vertices (mesh_id, id, halfedge, x, y, z) VALUES ({mesh_id}, {v}, {h}, {x}, 0, 0)"
        ))
    rows = [(0, 0, 2, 4, 1, 0, 0), (2, 1, 4, 0, 3, 1, 0), (4, 2, 0, 2, 5, 2, 0),
            (1, 1, 5, 3, 0, 0, None), (3, 2, 1, 5, 2, 1, None), (5, 0, 3, 1, 4, 2, None)]
    for h, origin, nxt, prev, twin, edge, polygon in rows:
        poly = "NULL" if polygon is None else polygon
        conn.execute(sa.text(
            "INSERT INTO halfedges (mesh_id, id, origin, next, prev, twin, edge, polygon) "
            f"VALUES ({mesh_id}, {h}, {origin}, {nxt}, {prev}, {twin}, {edge}, {poly})"
        ))
    for e in range(3):
        conn.execute(sa.text(f"INSERT INTO edges (mesh_id, id, halfedge) VALUES ({mesh_id}, {e}, {2 * e})"))
    conn.execute(sa.text(f"INSERT INTO polygons (mesh_id, id, halfedge) VALUES ({mesh_id}, 0, 0)"))
    if "revisions" in sa.inspect(conn).get_table_names():
        for table in ("vertices", "halfedges", "edges", "polygons"):
            conn.execute(sa.text(f"UPDATE {table} SET rev = 1"))
        conn.execute(sa.text("UPDATE meshes SET kept_from = 1"))
        conn.execute(sa.text(
            f"INSERT INTO revisions (mesh_id, number, committed_at) VALUES ({mesh_id}, 1, CURRENT_TIMESTAMP)"
        ))
    conn.commit()


@pytest.mark.parametrize("start", [r for r in migrate.revisions() if r != migrate.head_revision()])
def test_upgrade_from_every_earlier_revision_keeps_meshes(db_url, engine, start):
    with engine.connect() as conn:
        migrate.upgrade(conn, start)
        _store_triangle_by_hand(conn)
    with pytest.raises(hestore.SchemaVersionError):
        hestore.open(db_url)
    migrate.upgrade_database(db_url)
    with engine.connect() as conn:
        assert migrate.current_revision(conn) == migrate.head_revision()
        assert _differences(conn) == []
    with hestore.open(db_url) as store:
        mesh = store.mesh("old")
        assert mesh.check() == [] and mesh.revision == 1
        assert mesh.counts() == hestore.Counts(3, 6, 3, 1)
        assert mesh.vertex(1).position == (1.0, 0.0, 0.0)
        assert mesh.properties("vertex") == {}
        mesh.add_property("vertex", "t", "float64", default=0.5)
        mesh.vertex(2)["t"] = 2.0
        assert mesh.property_array("vertex", "t")[1].tolist() == [0.5, 0.5, 2.0]
        assert mesh.add_vertex().id == 3  # the counters survived the upgrade


def test_downgrade_from_head_drops_properties_and_keeps_meshes(db_url, engine):
    with hestore.open(db_url) as store:
        mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
        mesh.add_property("polygon", "label", "str", default="")
        mesh.polygon(0)["label"] = "kept?"
    with engine.connect() as conn:
        migrate.downgrade(conn, "0002")
        names = set(sa.inspect(conn).get_table_names())
        assert not ADDED["0003"] & names
        assert conn.execute(sa.text("SELECT count(*) FROM halfedges")).scalar() == 6
        migrate.upgrade(conn)
    with hestore.open(db_url) as store:
        mesh = store.mesh("t")
        assert mesh.check() == [] and mesh.properties("polygon") == {}


def _triangle_at_0003(engine, revision: int) -> None:
    """A database at 0003 holding the hand-made triangle at ``revision``, with a vertex property and one value."""
    with engine.connect() as conn:
        migrate.upgrade(conn, "0003")
        _store_triangle_by_hand(conn)
        conn.execute(sa.text("UPDATE meshes SET revision = :r, next_property = 1 WHERE name = 'old'"), {"r": revision})
        mesh_id = conn.execute(sa.text("SELECT id FROM meshes WHERE name = 'old'")).scalar_one()
        conn.execute(sa.text(
            f"INSERT INTO properties VALUES ({mesh_id}, 0, 'vertex', 't', 'float64', NULL, '0.5')"
        ))
        conn.execute(sa.text(f"INSERT INTO property_reals VALUES ({mesh_id}, 0, 1, 0, 7.0, NULL, NULL, NULL)"))
        conn.commit()


TRIANGLE_CREATED = {
    "vertex": {"created": 3, "removed": 0, "changed": 0},
    "halfedge": {"created": 6, "removed": 0, "changed": 0},
    "edge": {"created": 3, "removed": 0, "changed": 0},
    "polygon": {"created": 1, "removed": 0, "changed": 0},
}


def test_upgrade_from_0003_makes_the_current_state_the_first_kept_revision(db_url, engine):
    _triangle_at_0003(engine, 1)
    migrate.upgrade_database(db_url)
    with hestore.open(db_url) as store:
        mesh = store.mesh("old")
        assert mesh.revision == 1 and mesh.check() == []
        [first] = mesh.history()
        assert first.number == 1 and first.message == "the state when history began to be kept"
        assert first.committed_at.tzinfo is not None
        assert first.changes == TRIANGLE_CREATED
        state = (mesh.to_arrays().positions.tolist(), mesh.to_arrays().polygons.tolist(),
                 mesh.property_array("vertex", "t")[1].tolist())
        assert state[2] == [0.5, 7.0, 0.5]
        view = mesh.at(1)
        assert (view.to_arrays().positions.tolist(), view.to_arrays().polygons.tolist(),
                view.property_array("vertex", "t")[1].tolist()) == state
        assert view.check() == [] and view.counts() == hestore.Counts(3, 6, 3, 1)
        # the empty revision 0 from before history was kept is not kept
        with pytest.raises(hestore.RevisionNotFoundError, match="no longer kept"):
            mesh.at(0)
        with pytest.raises(hestore.RevisionNotFoundError):
            mesh.undo()  # its revision 1 cannot be undone: revision 0 is not kept
        # an edit makes revision 2 ...
        mesh.set_position(mesh.vertex(0), (0.0, 0.0, 1.0))
        mesh.vertex(1)["t"] = 8.0
        with store.transaction(message="more"):
            v = mesh.add_vertex((2.0, 2.0, 2.0))
            mesh.remove_polygon(mesh.polygon(0))
        assert mesh.revision == 4 and [r.number for r in mesh.history()] == [4, 3, 2, 1]
        assert v.id == 3  # the counters survived
        d = mesh.diff(1, 4)
        assert d.changed["vertex"] == [0, 1] and d.created["vertex"] == [3] and d.removed["polygon"] == [0]
        # ... and undo goes back to the upgraded state, not past it
        for _ in range(3):
            mesh.undo()
        assert (mesh.to_arrays().positions.tolist(), mesh.to_arrays().polygons.tolist(),
                mesh.property_array("vertex", "t")[1].tolist()) == state
        assert mesh.check() == [] and mesh.counts() == hestore.Counts(3, 6, 3, 1)
        with pytest.raises(hestore.RevisionNotFoundError):
            mesh.undo()


def test_upgrade_from_0003_of_a_mesh_at_a_later_revision(db_url, engine):
    _triangle_at_0003(engine, 5)
    migrate.upgrade_database(db_url)
    with hestore.open(db_url) as store:
        mesh = store.mesh("old")
        assert mesh.revision == 5 and [r.number for r in mesh.history()] == [5]
        assert mesh.at(5).counts() == hestore.Counts(3, 6, 3, 1)
        for r in (0, 1, 4):
            with pytest.raises(hestore.RevisionNotFoundError):
                mesh.at(r)
        mesh.add_vertex((1.0, 1.0, 1.0))
        assert mesh.revision == 6 and mesh.diff(5, 6).created["vertex"] == [3]
        mesh.undo()
        assert mesh.counts() == hestore.Counts(3, 6, 3, 1) and mesh.vertex(1)["t"] == 7.0


def test_the_first_kept_revision_of_an_upgraded_mesh_reports_its_content_whatever_its_number(db_url, engine):
    _triangle_at_0003(engine, 5)
    migrate.upgrade_database(db_url)
    with hestore.open(db_url) as store:
        [first] = store.mesh("old").history()
        assert first.number == 5
        assert first.changes == TRIANGLE_CREATED  # as for an upgraded mesh at revision 1


def _history_keys(conn: sa.Connection) -> dict:
    """Each history table's primary key columns, in order, and its other indexes."""
    inspect = sa.inspect(conn)
    return {t: (inspect.get_pk_constraint(t)["constrained_columns"], [ix["name"] for ix in inspect.get_indexes(t)])
            for t in sorted(HISTORY)}


def test_0005_keys_history_by_revision_and_keeps_it_both_ways(db_url, engine):
    with hestore.open(db_url) as store:
        mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [[0, 1, 2], [1, 3, 2]]).mesh
        mesh.add_property("vertex", "w", "float64", default=0.0)
        mesh.set_position(mesh.vertex(3), (2.0, 2.0, 0.0))
        mesh.vertex(0)["w"] = 1.5
        mesh.flip_edge(mesh.find_halfedge(mesh.vertex(1), mesh.vertex(2)).edge)
        mesh.remove_polygon(mesh.polygon(1))
        revisions = [r.number for r in mesh.history()]

        def states():
            return {r: (mesh.at(r).to_arrays().positions.tolist(), mesh.at(r).to_arrays().polygons.tolist(),
                        mesh.at(r).property_array("vertex", "w")[1].tolist() if r > 2 else None)
                    for r in revisions}

        before = states()
    with engine.connect() as conn:
        assert _history_keys(conn)["vertices_history"] == (["mesh_id", "rev_to", "id"], [])
        assert _history_keys(conn)["property_reals_history"][0] == ["mesh_id", "rev_to", "property", "id", "part"]
        migrate.downgrade(conn, "0004")
        assert _history_keys(conn)["vertices_history"] == (
            ["mesh_id", "id", "rev_to"], ["ix_vertices_history_rev_to"])
        migrate.upgrade(conn)
        assert _differences(conn) == []
        assert all(pk[:2] == ["mesh_id", "rev_to"] and not ix for pk, ix in _history_keys(conn).values())
    with hestore.open(db_url) as store:
        mesh = store.mesh("t")
        assert states() == before
        assert mesh.check() == []
        mesh.undo()
        mesh.undo()
        now = (mesh.to_arrays().positions.tolist(), mesh.to_arrays().polygons.tolist())
        assert now == tuple(before[revisions[2]][:2])
