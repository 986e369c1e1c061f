"""Make the pictures in docs/img/ (run from the repository root: ``python docs/pictures.py``).

The teapot of ``docs/render.md`` comes from the shared test meshes (see
``tests/meshes.py``; set ``HESTORE_TEST_MESHES`` where they are elsewhere), read
into an in-memory store: nothing is written but the pictures.
"""

from __future__ import annotations

import pathlib
import sys

import matplotlib

matplotlib.use("Agg")

import hestore  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

from meshes import shared_meshes  # noqa: E402

#: Pictures committed to the repository stay below this size.
LIMIT = 200_000


def main() -> None:
    folder = shared_meshes()
    if folder is None:
        sys.exit("the shared test meshes are not here: set HESTORE_TEST_MESHES")
    out = HERE / "img"
    out.mkdir(exist_ok=True)
    with hestore.open("sqlite://") as store:
        teapot = store.import_file(folder / "teapot.obj").mesh
        path = out / "teapot.png"
        teapot.render(path, size=(560, 380), view=(-75, 60))
        size = path.stat().st_size
        print(f"{path.relative_to(HERE.parent)}: {size:,} bytes")
        if size > LIMIT:
            sys.exit(f"{path} is {size:,} bytes, more than {LIMIT:,}: make it smaller before committing it")


if __name__ == "__main__":
    main()
