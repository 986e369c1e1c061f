"""History of a mesh: its revisions, what changed between two, and going back (SPEC §4.1).

This module owns the meaning of history on top of the row versions the
history engine reads and restores (`hestore._timeline`): `Revision` and
`Diff`, the net changes between two revisions (`diff`, computed from the
rows that differ, so an element created and removed in between appears
nowhere and a value written back unchanged is no change), the list of kept
revisions (`history`), and the undo stack (`undo`, `redo`, `revert`).
Reads of a past revision are the session's (`hestore._session.Session.view`);
the mesh facade wraps them as ``mesh.at(r)``.

The undo stack is derived from what each kept revision records it did
(an undo or redo of which revision), so it survives reconnecting and is the
same for every process.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from datetime import datetime

from hestore import schema
from hestore import _timeline as timeline
from hestore.errors import InvalidInputError, RevisionNotFoundError, shown
from hestore._journal import KINDS
from hestore._values import check_integer, check_revision, property_of, value_of
from hestore._session import MeshRef

__all__ = [
    "Revision", "Diff", "KINDS", "history", "diff", "undo", "redo", "revert", "prune", "changes_of",
]

_VALUE_TABLES = [t.name for t in schema.VALUE_TABLES]


@dataclass(frozen=True)
class Revision:
    """One kept revision of a mesh.

    Attributes
    ----------
    number : int
        The revision (1 is the first; the mesh's ``revision`` is the latest).
    committed_at : datetime
        When it was written, in UTC (timezone-aware).
    message : str or None
        The transaction's message; None for a single call outside a block;
        ``"undo of revision 7"``, ``"redo of revision 7"``, ``"revert to
        revision 3"`` for those.
    changes : dict
        ``{kind: {"created": n, "removed": n, "changed": n}}`` for each kind
        of element, net (see `Diff`).
    """

    number: int
    committed_at: datetime
    message: str | None
    changes: dict = field(repr=False)


@dataclass(frozen=True)
class Diff:
    """What differs between two revisions of a mesh: ``{kind: sorted list of ids}`` per attribute.

    Net: the state at one compared with the state at the other. An element
    is *changed* when one of its stored references (``origin``, ``next``, ``twin``, …), its position
    or one of its property values differs; writing back an equal value is
    no change, and an element created and removed in between appears
    nowhere.
    """

    created: dict
    removed: dict
    changed: dict

    def counts(self) -> dict:
        """``{kind: {"created": n, "removed": n, "changed": n}}``."""
        return {
            k: {"created": len(self.created[k]), "removed": len(self.removed[k]), "changed": len(self.changed[k])}
            for k in KINDS
        }

    def __bool__(self) -> bool:
        return any(self.created[k] or self.removed[k] or self.changed[k] for k in KINDS)


def diff_of(versions: dict) -> Diff:
    """A `Diff` from `hestore._timeline.versions`' rows at the two revisions."""
    created, removed, changed = ({k: set() for k in KINDS} for _ in range(3))
    for kind in KINDS:
        before, after = ({row[0]: row for row in rows} for rows in versions[schema.KINDS[kind].table.name])
        created[kind] = set(after) - set(before)
        removed[kind] = set(before) - set(after)
        changed[kind] = {i for i in set(before) & set(after) if before[i] != after[i]}
    catalogue_a, catalogue_b = versions[schema.properties.name]
    declared = {row[0]: property_of(*row) for row in [*catalogue_a, *catalogue_b]}
    for table in _VALUE_TABLES:
        # Compared as values, not rows: an element without a row has the default, so writing the
        # default it already had, or unsetting a stored default, changes nothing.
        found: dict = {}
        for side, rows in enumerate(versions[table]):
            for row in rows:
                found.setdefault(row[:2], ([], []))[side].append(row[2:])
        for (pid, i), (before, after) in found.items():
            prop = declared.get(pid)
            if prop is not None and not _same(value_of(prop, before), value_of(prop, after)):
                changed[prop.kind].add(i)
    for kind in KINDS:
        changed[kind] -= created[kind] | removed[kind]
    return Diff(*({k: sorted(v[k]) for k in KINDS} for v in (created, removed, changed)))


def _same(x, y) -> bool:
    """Equal values, NaN equal to NaN (a float value may be NaN; it is stored as NULL)."""
    if isinstance(x, tuple) and isinstance(y, tuple):
        return len(x) == len(y) and all(_same(p, q) for p, q in zip(x, y))
    return x == y or (isinstance(x, float) and isinstance(y, float) and x != x and y != y)


def diff(ref: MeshRef, a: int, b: int) -> Diff:
    """What differs between revisions ``a`` and ``b`` of ``mesh`` (``created``: in ``b``, not in ``a``).

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.import_arrays("tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    >>> mesh.set_position(mesh.vertex(2), (0, 2, 0))
    >>> d = mesh.diff(1, 2)
    >>> d.changed["vertex"], d.created["vertex"]
    ([2], [])
    """
    a, b = check_revision(a), check_revision(b)
    return diff_of(timeline.versions(ref, a, b))


def changes_of(ref: MeshRef, number: int, stored: str | None) -> dict:
    """The ``changes`` of one revision: stored for a bulk revision, else its diff with the one before."""
    if stored is not None:
        return json.loads(stored)
    return diff_of(timeline.versions(ref, number - 1, number, check=False)).counts()


def history(ref: MeshRef, limit: int | None = None) -> list[Revision]:
    """The kept revisions of ``mesh`` from 1 up, newest first (at most ``limit``).

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.create_mesh("m")
    >>> with store.transaction(message="two vertices"):
    ...     a, b = mesh.add_vertex(), mesh.add_vertex()
    >>> [(r.number, r.message, r.changes["vertex"]["created"]) for r in mesh.history()]
    [(1, 'two vertices', 2)]
    """
    if limit is not None:
        limit = check_integer(limit, "limit")
        if not 0 <= limit < 2**63:  # SQL takes no count beyond 64 bits
            raise InvalidInputError(f"limit is a number of revisions from 0 to 2**63 - 1, not {shown(limit)}")
    kept = [
        Revision(int(n), at, message, changes_of(ref, int(n), stored))
        for n, at, message, stored, _action, _target in timeline.revisions(ref, limit)
    ]
    if not kept:
        return kept
    # Another process may have pruned meanwhile, taking rows some changes were read from: those
    # revisions are gone. A prune only moves forward, so what is kept now was kept all along.
    oldest = timeline.oldest_kept(ref)
    return [r for r in kept if r.number >= oldest]


def _stacks(ref: MeshRef) -> tuple[list[int], list[int]]:
    """The undo stack (revisions whose change can be undone) and the redo stack, oldest first.

    Replayed from the kept revisions' actions: an ordinary revision (a
    revert too) is pushed on the undo stack and clears the redo stack; an
    undo moves its target to the redo stack; a redo pushes itself back.
    """
    undo_stack: list[int] = []
    redo_stack: list[int] = []
    for number, _at, _message, _changes, action, target in timeline.revisions(ref, newest_first=False):
        if action == "undo":
            if undo_stack and undo_stack[-1] == target:
                undo_stack.pop()
            redo_stack.append(target)
        elif action == "redo":
            if redo_stack and redo_stack[-1] == target:
                redo_stack.pop()
            undo_stack.append(number)
        else:
            undo_stack.append(number)
            redo_stack.clear()
    return undo_stack, redo_stack


def revert(ref: MeshRef, revision: int, message: str | None = None) -> int:
    """Commit a new revision whose content equals ``mesh.at(revision)``; return its number."""
    revision = check_revision(revision)
    return timeline.restore(ref, revision, message or f"revert to revision {revision}", "revert", revision)


def undo(ref: MeshRef) -> int:
    """Undo the most recent change not yet undone: a new revision equal to the state before it."""
    return _step(ref, "undo")


def redo(ref: MeshRef) -> int:
    """Re-apply the most recently undone change: a new revision equal to the state after it."""
    return _step(ref, "redo")


def _step(ref: MeshRef, action: str) -> int:
    session = ref.session
    timeline.restorable(ref, action)
    # What to restore is decided under the writer lock, from the history as committed then: a stack
    # read before the lock is granted may miss a revision another writer committed meanwhile, and
    # restoring from it would throw that edit away.
    with session.scope():
        session.lock(ref)
        stack = _stacks(ref)[0 if action == "undo" else 1]
        if not stack:
            raise RevisionNotFoundError(f"mesh {ref.name!r} has nothing to {action}")
        target = stack[-1]
        state = target - 1 if action == "undo" else target  # before the change, or after it
        return timeline.restore(ref, state, f"{action} of revision {target}", action, target)


def prune(ref: MeshRef, keep: int) -> int:
    """Keep the newest ``keep`` revisions of ``mesh`` (at least 1: the current one); return the oldest kept."""
    keep = check_integer(keep, "keep")
    if keep < 1:
        raise InvalidInputError(f"keep must be at least 1 (the current revision), not {shown(keep)}")
    return timeline.prune(ref, keep)
