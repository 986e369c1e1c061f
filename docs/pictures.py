"""Make the pictures in docs/img/ (run from the repository root: ``python docs/pictures.py``).

Every picture is drawn by hestore itself (`Mesh.plot`, `Mesh.render`) from a
mesh read into an in-memory store: nothing is written but the pictures.

- ``demo.png``: the mesh ``hestore demo`` builds (`hestore.cli.demo.run`);
- ``navigation.png``: a small mesh with its vertex ids, for the navigation tables;
- ``repair-hourglass.png``: ``hourglass_ico.obj`` imported with ``on_error="skip"`` and with ``on_error="split"``;
- ``teapot.png``: the Newell teapot, ``teapot.obj``.

The last two come from the shared test meshes (see ``tests/meshes.py``; set
``HESTORE_TEST_MESHES`` where they are elsewhere); they are read where they
are, never copied.
"""

from __future__ import annotations

import pathlib
import sys

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402

import hestore  # noqa: E402
from hestore.cli import demo  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from meshes import shared_meshes  # noqa: E402

#: Pictures committed to the repository stay below this size.
LIMIT = 150_000


def demo_mesh(store: hestore.Store, path: pathlib.Path) -> None:
    mesh = demo.run(store, out=lambda line: None)
    mesh.render(path, size=(760, 300), dpi=80)


def navigation(store: hestore.Store, path: pathlib.Path) -> None:
    """A hexagon of six triangles around vertex 0, and a quad beside it: small enough to read every id."""
    xyz = [(0, 0, 0), (2, 0, 0), (1, 1.7, 0), (-1, 1.7, 0), (-2, 0, 0), (-1, -1.7, 0), (1, -1.7, 0)]
    xyz += [(4, 0, 0), (3, 1.7, 0)]
    polygons = [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5], [0, 5, 6], [0, 6, 1], [1, 7, 8, 2]]
    mesh = store.import_arrays("hexagon", xyz, polygons).mesh
    fig, ax = plt.subplots(figsize=(7.5, 4.6), dpi=100)
    mesh.plot(ax, labels="all")
    ax.get_legend().remove()  # one boundary loop: the legend would only cover a corner
    low, high = ax.get_ylim()  # room for the boundary's arrows, outside the mesh
    ax.set_ylim(low - 0.06 * (high - low), high + 0.06 * (high - low))
    ax.set_title("vertex ids, and each half-edge's id on its arrow, on its polygon's side", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def repair(store: hestore.Store, folder: pathlib.Path, path: pathlib.Path) -> None:
    """Side by side: what a skipping import keeps of the hourglass, and what a splitting one keeps."""
    source = folder / "hourglass_ico.obj"
    skip = store.import_file(source, "hourglass-skip", on_error="skip")
    split = store.import_file(source, "hourglass-split", on_error="split")
    fig, (left, right) = plt.subplots(1, 2, figsize=(8, 4), dpi=80)
    for ax, report, what in [(left, skip, 'on_error="skip"'), (right, split, 'on_error="split"')]:
        report.mesh.plot(ax, view=(-20, 20))
        ax.set_title(f"{what}: {report.polygons} polygons, {len(report.skipped)} skipped", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def teapot(store: hestore.Store, folder: pathlib.Path, path: pathlib.Path) -> None:
    store.import_file(folder / "teapot.obj").mesh.render(path, size=(480, 330), dpi=80, view=(-75, 60))


def main() -> None:
    folder = shared_meshes()
    if folder is None:
        sys.exit("the shared test meshes are not here: set HESTORE_TEST_MESHES")
    out = HERE / "img"
    out.mkdir(exist_ok=True)
    too_large = []
    with hestore.open("sqlite://") as store:
        for name, draw in [
            ("demo.png", lambda p: demo_mesh(store, p)),
            ("navigation.png", lambda p: navigation(store, p)),
            ("repair-hourglass.png", lambda p: repair(store, folder, p)),
            ("teapot.png", lambda p: teapot(store, folder, p)),
        ]:
            path = out / name
            draw(path)
            size = path.stat().st_size
            print(f"{path.relative_to(HERE.parent)}: {size:,} bytes")
            if size > LIMIT:
                too_large.append(f"{path} is {size:,} bytes, more than {LIMIT:,}")
    if too_large:
        sys.exit("make these smaller before committing them:\n" + "\n".join(too_large))


if __name__ == "__main__":
    main()
