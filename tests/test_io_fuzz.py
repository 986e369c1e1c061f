"""Seeded fuzzing of the mesh file readers (`hestore.io`); no database needed.

Small real files from the shared meshes folder are mutated — truncated,
bytes flipped, inserted or deleted, header counts replaced by huge, negative
or garbage numbers, PLY types swapped, lines duplicated — and each mutant is
read. A mutant must either read fine or raise `InvalidInputError`; anything
else (a bare ValueError, MemoryError, struct.error, ...), a read that takes
too long or one that allocates far more than the file could justify fails
the test.

Every mutation is derived from a string seed (``"{file}:{case}"``), so a
failure reproduces exactly: the assertion message names the seed and the
mutations, and `mutate` rebuilds the mutant from them.
"""

from __future__ import annotations

import pathlib
import random
import re
import time
import tracemalloc

import numpy as np
import pytest
from meshes import require_shared_meshes

from hestore import io as mesh_io
from hestore.errors import InvalidInputError

SOURCES = [
    "cube_poly.off",
    "torus_quad.off",
    "fan3.obj",
    "dodecahedron_poly.obj",
    "cube-minimal.ply",
    "meshlab.ply",
    "sphere840.ply",
    "bob_small.ply",
]
# bob_small.ply is the only binary PLY above, and its faces are all
# triangles: this one has mixed arities, so that the record-by-record walk
# of binary lists is fuzzed too.
DERIVED = "cube_poly.off as binary big-endian PLY"

CASES = 600  # mutants per source file
SECONDS = 5.0  # processor time per read (which a busy machine does not add to): generous, catches runaway work
# Per read: the soup and the parsing temporaries of a file of a few KB fit
# in a few MB; a reader that trusts a header count allocates gigabytes.
PEAK_BYTES = 64 << 20

GARBAGE_COUNTS = [
    b"4294967296",
    b"9223372036854775807",
    b"9223372036854775808",
    b"18446744073709551616",
    b"99999999999999999999",
    b"9" * 5000,
    b"-1",
    b"-9223372036854775808",
    b"1e9",
    b"3.0",
    b"nan",
    b"0x10",
    b"",
    b"\xd9\xa3",  # ARABIC-INDIC DIGIT THREE
    b"\xff\xfe",
    b"\x00",
    b"0",
    b"65536",
    b"2147483648",
]
SPECIAL_BYTES = b"\x00\n\r\t #-+./0123456789eE\xff\x80"
PLY_TYPES = [b"char", b"uchar", b"short", b"ushort", b"int", b"uint", b"float", b"double", b"int8", b"float64"]


def _header_end(data: bytes, name: str) -> int:
    """Where the header (the part holding the counts) ends, for targeted mutations."""
    if name.endswith(".ply"):
        at = data.find(b"end_header")
        return len(data) if at < 0 else at
    if name.endswith(".off"):
        counts = re.search(rb"^\s*\d+\s+\d+(\s+\d+)?\s*$", data, re.MULTILINE)
        return counts.end() if counts else min(len(data), 64)
    return len(data)  # OBJ: every index is a count of sorts


def _replace_number(data: bytes, name: str, rng: random.Random) -> tuple[bytes, str]:
    numbers = list(re.finditer(rb"-?\d+(\.\d+)?", data[: _header_end(data, name)]))
    if not numbers:
        return data, "no number to replace"
    number = rng.choice(numbers)
    garbage = rng.choice(GARBAGE_COUNTS)
    shown = garbage if len(garbage) < 30 else garbage[:8] + b"...(%d bytes)" % len(garbage)
    return data[: number.start()] + garbage + data[number.end() :], f"number at {number.start()} -> {shown!r}"


def _swap_type(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    end = data.find(b"end_header")
    types = list(re.finditer(rb"\b(" + b"|".join(PLY_TYPES) + rb")\b", data[: max(end, 0)]))
    if not types:
        return data, "no type to swap"
    found = rng.choice(types)
    new = rng.choice(PLY_TYPES)
    return data[: found.start()] + new + data[found.end() :], f"type at {found.start()} -> {new.decode()}"


def _duplicate_line(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    lines = data.split(b"\n")
    i = rng.randrange(len(lines))
    times = rng.choice([1, 1, 2, 100])
    return b"\n".join(lines[:i] + [lines[i]] * (times + 1) + lines[i + 1 :]), f"line {i + 1} repeated {times}x"


def mutate(data: bytes, name: str, seed: str) -> tuple[bytes, list[str]]:
    """The mutant of ``data`` for ``seed``, and what was done to it."""
    rng = random.Random(seed)
    done = []
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        kind = rng.choice(["truncate", "flip", "insert", "delete", "number", "number", "type", "duplicate"])
        if not data:
            kind = "insert"
        if kind == "truncate":
            at = rng.randrange(len(data))
            data, what = data[:at], f"truncated at {at}"
        elif kind == "flip":
            spots = sorted(rng.randrange(len(data)) for _ in range(rng.choice([1, 1, 2, 8])))
            out = bytearray(data)
            for at in spots:
                out[at] = rng.choice([rng.randrange(256), rng.choice(SPECIAL_BYTES)])
            data, what = bytes(out), f"bytes at {spots} replaced"
        elif kind == "insert":
            at = rng.randrange(len(data) + 1)
            size = rng.choice([1, 1, 4, 16])
            extra = bytes(rng.choice([rng.randrange(256), rng.choice(SPECIAL_BYTES)]) for _ in range(size))
            data, what = data[:at] + extra + data[at:], f"inserted {extra!r} at {at}"
        elif kind == "delete":
            at = rng.randrange(len(data))
            size = rng.choice([1, 1, 4, 16])
            data, what = data[:at] + data[at + size :], f"deleted {size} bytes at {at}"
        elif kind == "number":
            data, what = _replace_number(data, name, rng)
        elif kind == "type" and name.endswith(".ply"):
            data, what = _swap_type(data, rng)
        else:
            data, what = _duplicate_line(data, rng)
        done.append(what)
    return data, done


def _source(name: str) -> tuple[bytes, str]:
    """The bytes of a source file, and the extension its mutants get."""
    folder = require_shared_meshes()
    if name == DERIVED:
        soup = mesh_io.read(folder / "cube_poly.off")
        data = _binary_big_endian_ply(soup)
        return data, ".ply"
    return (folder / name).read_bytes(), pathlib.Path(name).suffix


def _binary_big_endian_ply(soup) -> bytes:
    counts = np.diff(soup.offsets)
    head = (
        "ply\nformat binary_big_endian 1.0\ncomment derived from cube_poly.off\n"
        f"element vertex {len(soup.positions)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(counts)}\nproperty list uchar int vertex_indices\nproperty uchar flags\nend_header\n"
    ).encode()
    body = soup.positions.astype(">f4").tobytes()
    for i, k in enumerate(counts.tolist()):
        body += bytes([k]) + soup.indices[soup.offsets[i] : soup.offsets[i + 1]].astype(">i4").tobytes() + b"\x07"
    return head + body


@pytest.mark.parametrize("name", SOURCES + [DERIVED])
def test_mutated_files_read_fine_or_raise_invalid_input(name, tmp_path):
    original, suffix = _source(name)
    mesh_io.read(_put(tmp_path / f"original{suffix}", original))  # the unmutated file reads
    path = tmp_path / f"mutant{suffix}"
    outcomes = {"read": 0, "refused": 0}
    for case in range(CASES):
        seed = f"{name}:{case}"
        data, done = mutate(original, name, seed)
        _put(path, data)
        context = f"seed {seed!r} ({'; '.join(done)}), {len(data)} bytes"
        soup = None
        tracemalloc.start()
        started = time.process_time()
        try:
            soup = mesh_io.read(path)
            outcomes["read"] += 1
        except InvalidInputError as e:
            outcomes["refused"] += 1
            where = re.match(re.escape(str(path)) + r":(\d+|byte \d+): ", str(e))
            assert where, f"{context}: the message does not name the file and the line or byte: {e}"
        except Exception as e:  # noqa: BLE001 - anything else is the bug this test looks for
            pytest.fail(f"{context}: {type(e).__name__}: {e}")
        finally:
            seconds = time.process_time() - started
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
        assert seconds < SECONDS, f"{context}: the read took {seconds:.1f} s"
        assert peak < PEAK_BYTES, f"{context}: the read allocated {peak / 2**20:.0f} MiB at its peak"
        if soup is not None:
            assert_consistent(soup, suffix == ".ply" and b"format ascii" not in data[:200], context)
    # The mutations must not all be trivially fatal, nor all harmless.
    assert outcomes["read"] > 0 and outcomes["refused"] > 0, outcomes


def assert_consistent(soup, binary: bool, context: str) -> None:
    """What the builder relies on in every soup a reader returns."""
    positions, offsets, indices, lines = soup.positions, soup.offsets, soup.indices, soup.lines
    assert positions.dtype == np.float64 and positions.ndim == 2 and positions.shape[1] == 3, context
    assert np.isfinite(positions).all(), context
    assert offsets.dtype == np.int64 and indices.dtype == np.int64, context
    assert offsets[0] == 0 and offsets[-1] == len(indices) and (np.diff(offsets) >= 0).all(), context
    if lines is None:
        assert binary, context
    else:
        assert lines.dtype == np.int64 and len(lines) == len(offsets) - 1 and (np.diff(lines) > 0).all(), context


def test_mutations_reproduce_from_their_seed():
    data = b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    assert mutate(data, "x.off", "x.off:7") == mutate(data, "x.off", "x.off:7")
    assert {mutate(data, "x.off", f"x.off:{i}")[0] for i in range(20)} != {data}


def _put(path: pathlib.Path, data: bytes) -> pathlib.Path:
    path.write_bytes(data)
    return path


STORE_CASES = 40  # mutants per source file imported into a store, on each backend


@pytest.mark.slow
@pytest.mark.parametrize("name", SOURCES)
def test_mutated_files_import_whole_or_not_at_all(name, store, tmp_path):
    """Through a store: every failure is typed, nothing is stored, and what is stored is valid."""
    import hestore
    from helpers import dump

    data, _ = _source(name)
    suffix = pathlib.Path(name).suffix
    for case in range(STORE_CASES):
        seed = f"store:{name}:{case}"
        mutant, what = mutate(data, name, seed)
        path = _put(tmp_path / f"m{case}{suffix}", mutant)
        before = dump(store)
        context = f"seed {seed!r}, mutations {what}"
        t0 = time.process_time()
        try:
            report = store.import_file(path, f"m{case}", on_error="skip")
        except hestore.HestoreError as exc:
            assert isinstance(exc, (InvalidInputError, hestore.TopologyError)), f"{context}: {exc!r}"
            assert dump(store) == before, f"{context}: a refused import stored something"
        else:
            assert report.mesh.check() == [], context
            assert report.mesh.counts().polygons == report.polygons, context
        assert time.process_time() - t0 < SECONDS, f"{context}: took too long"
