"""Draw the module layers, ``docs/img/layers.svg``, from the code: ``python docs/layers.py``.

The picture on the architecture page is made from two things and nothing else:

- the layers, as the import-linter ``layers`` contracts in ``pyproject.toml`` declare them (the one whose
  container is the package, and those of its subpackages, such as ``hestore.cli``, drawn inside their box);
- the imports, read with `ast` from every module under ``src/hestore``: at module level, inside functions and
  under ``if TYPE_CHECKING:`` alike (the contracts count annotation imports too), relative ones resolved.
  An import of the package ``hestore`` itself (``import hestore``, ``from hestore import open``) names no layer
  and is left out, as is the package's ``__init__``, which is in no layer.

One box per layer, top to bottom as the contract orders them, listing its modules (``a | b``: independent
modules, which may not import each other). One arrow per pair of layers that import one another, however
many imports it stands for (the line's width grows with their number; in a browser, hovering over an arrow
lists them). Imports go down, on the right. An import that breaks a contract — upward, or between
independent modules of one layer — is red, on the left; one from or to a module in no layer (an "unlayered"
box at the bottom) is orange. The picture only shows: ``lint-imports`` is what enforces the contracts.

The file is SVG written as text, the same bytes for the same code: no tool draws it, nothing runs when it
is viewed. Run from anywhere::

    python docs/layers.py           # write docs/img/layers.svg
    python docs/layers.py --check   # exit status 1 if it is not what the code draws now

The script is also an mkdocs hook (``hooks:`` in ``mkdocs.yml``): the site build fails while the picture
in the repository differs from the one the code draws, and says which command redraws it. It needs only
the standard library, so the hook costs the build nothing to import.
"""

from __future__ import annotations

import ast
import math
import pathlib
import sys
import tomllib
from dataclasses import dataclass, field
from html import escape

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
PICTURE = HERE / "img" / "layers.svg"
COMMAND = "python docs/layers.py"

#: Where a layer's text goes: a monospace font, whose width per character is known.
FONT = "DejaVu Sans Mono, Menlo, Consolas, monospace"
FONT_SIZE = 12
CHAR = 0.61 * FONT_SIZE
LINE = 16
PAD = 8
#: Between two horizontal lines ending on one side of a box, and between two vertical lanes.
PORT = 8
LANE = 12
GAP = 14
WIDTH = 600

GREY = "#5f6b7a"
RED = "#d62728"
ORANGE = "#e67e00"


# --- the layers ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Layer:
    """One layer of a contract: its items (names below the container), whether they are independent of each other,
    and whether it is no layer of the contract but the modules that are in none."""

    items: tuple[str, ...]
    independent: bool
    unlayered: bool = False


@dataclass
class Stack:
    """A container's layers, top first, and the stacks of its items that have a contract of their own."""

    container: str
    layers: list[Layer]
    inner: dict[str, Stack] = field(default_factory=dict)


def parse_layer(text: str) -> Layer:
    """One entry of a contract's ``layers``: ``"a | b"`` (independent), ``"a : b"``, ``"(optional)"``.

    Examples
    --------
    >>> parse_layer("interop | render")
    Layer(items=('interop', 'render'), independent=True, unlayered=False)
    >>> parse_layer("(store)").items
    ('store',)
    """
    independent = "|" in text
    parts = text.replace(":", "|").split("|")
    return Layer(tuple(p.strip().strip("()").strip() for p in parts if p.strip()), independent)


def read_stack(pyproject: pathlib.Path) -> Stack:
    """The layers of ``[tool.importlinter]``: the root package's contract, with its subpackages' inside.

    A layers contract whose container is one item of the root's layers (``hestore.cli``) is drawn inside that
    item's box. Any other container is refused: the picture would have no place for it.
    """
    config = tomllib.loads(pyproject.read_text(encoding="utf-8"))["tool"]["importlinter"]
    root = config["root_package"]
    stacks: dict[str, Stack] = {}
    for contract in config.get("contracts", []):
        if contract.get("type") != "layers":
            continue
        if not contract.get("containers"):
            raise ValueError(f"the layers contract {contract.get('name')!r} has no containers: the picture needs them")
        for container in contract["containers"]:
            if container in stacks:
                raise ValueError(f"two layers contracts for {container}: the picture draws one")
            stacks[container] = Stack(container, [parse_layer(text) for text in contract["layers"]])
    if root not in stacks:
        raise ValueError(f"no layers contract has the container {root!r}: there is nothing to draw")
    top = stacks.pop(root)
    items = {f"{root}.{item}" for layer in top.layers for item in layer.items}
    for container, stack in sorted(stacks.items()):
        if container not in items:
            raise ValueError(
                f"the layers contract of {container} is not for one module of {root}'s own layers: "
                "the picture has no place for it"
            )
        top.inner[container.rsplit(".", 1)[1]] = stack
    return top


# --- the imports ---------------------------------------------------------------------------------------------


def find_modules(package: pathlib.Path) -> dict[str, pathlib.Path]:
    """Every module of the package in the folder ``package``, by dotted name (a package by its own name).

    Examples
    --------
    >>> sorted(find_modules(ROOT / "src" / "hestore"))[:2]
    ['hestore', 'hestore.__main__']
    """
    modules = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        if any(not part.isidentifier() for part in parts):  # a folder such as __pycache__ or a stray copy
            continue
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    return modules


def module_imports(name: str, path: pathlib.Path, modules: dict[str, pathlib.Path]) -> set[str]:
    """The modules of ``modules`` that module ``name`` imports anywhere in its source, relative imports resolved.

    ``from a import b`` imports ``a.b`` where that is a module, else ``a``.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()

    def known(dotted: str) -> str | None:
        while dotted and dotted not in modules:  # `import a.b.c` of a name inside a module: its module
            dotted = dotted.rpartition(".")[0]
        return dotted or None

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(known(alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else known(base))
    found.discard(None)
    found.discard(name)
    return found


def read_imports(package: pathlib.Path) -> tuple[list[str], set[tuple[str, str]]]:
    """The package's modules, and its imports as (importer, imported) pairs, the package itself left out."""
    modules = find_modules(package)
    root = package.name
    pairs = {
        (name, imported)
        for name, path in modules.items()
        if name != root
        for imported in module_imports(name, path, modules)
        if imported != root
    }
    return sorted(m for m in modules if m != root), pairs


# --- from modules to boxes -----------------------------------------------------------------------------------


def item_of(container: str, items: list[str], module: str) -> str | None:
    """The item of ``items`` (names below ``container``) that ``module`` is or is inside of, if any.

    Examples
    --------
    >>> item_of("hestore", ["io", "mesh"], "hestore.io.obj")
    'io'
    >>> item_of("hestore", ["io"], "hestore.iox") is None
    True
    """
    found = [item for item in items if module == f"{container}.{item}" or module.startswith(f"{container}.{item}.")]
    return max(found, key=len) if found else None


def first_child(container: str, module: str) -> str:
    """The name below ``container`` of the child that holds ``module``: ``io`` for ``hestore.io.obj``."""
    return module[len(container) + 1 :].split(".")[0]


@dataclass(frozen=True)
class Edge:
    """The imports from one box to another of one stack, and how they stand with the contract."""

    source: int
    target: int
    pairs: tuple[tuple[str, str], ...]
    colour: str

    @property
    def down(self) -> bool:
        return self.source < self.target


def place(stack: Stack, modules: list[str]) -> tuple[list[Layer], dict[str, tuple[int, str]]]:
    """The stack's layers (an "unlayered" one last, if a module is in none) and each module's (layer, item)."""
    items = [item for layer in stack.layers for item in layer.items]
    layer_of = {item: i for i, layer in enumerate(stack.layers) for item in layer.items}
    places, stray = {}, set()
    for module in modules:
        if not module.startswith(stack.container + "."):
            continue
        item = item_of(stack.container, items, module)
        if item is None:
            stray.add(first_child(stack.container, module))
            continue
        places[module] = (layer_of[item], item)
    layers = list(stack.layers)
    if stray:
        layers.append(Layer(tuple(sorted(stray)), independent=False, unlayered=True))
        for module in modules:
            if module.startswith(stack.container + ".") and module not in places:
                places[module] = (len(layers) - 1, first_child(stack.container, module))
    return layers, places


def edges(layers: list[Layer], places: dict[str, tuple[int, str]], imports: set[tuple[str, str]]) -> list[Edge]:
    """The imports between the stack's boxes, one edge per (importer's layer, imported's layer).

    Imports within one item (inside ``io``, inside ``cli``) are not the stack's: a package with a contract of its
    own draws them inside its box. Between two items of one layer an import is drawn only where it breaks the
    contract (independent items) or involves an unlayered module.
    """
    grouped: dict[tuple[int, int], list[tuple[str, str]]] = {}
    for a, b in sorted(imports):
        if a not in places or b not in places or places[a][1] == places[b][1]:
            continue
        (i, _), (j, _) = places[a], places[b]
        if i == j and not (layers[i].independent or layers[i].unlayered):
            continue
        grouped.setdefault((i, j), []).append((a, b))
    found = []
    for (i, j), pairs in sorted(grouped.items()):
        if layers[i].unlayered or layers[j].unlayered:
            colour = ORANGE
        elif i >= j:
            colour = RED
        else:
            colour = GREY
        found.append(Edge(i, j, tuple(pairs), colour))
    return found


# --- drawing -------------------------------------------------------------------------------------------------


def wrap(words: list[str], width: float) -> list[str]:
    """Words in lines of at most ``width`` pixels of the monospace font (a longer word gets a line of its own)."""
    lines: list[str] = []
    for word in words:
        if lines and (len(lines[-1]) + len(word)) * CHAR <= width:
            lines[-1] += word
        else:
            lines.append(word.lstrip())
    return [line.rstrip() for line in lines]


def label_words(layer: Layer, stack: Stack, modules: list[str]) -> list[str]:
    """The words of a layer's label: ``a |``, ``b``; a package's item with its modules: ``io (common, obj)``."""
    words = ["in no layer:"] if layer.unlayered else []
    for n, item in enumerate(layer.items):
        children = sorted(
            {first_child(f"{stack.container}.{item}", m) for m in modules if m.startswith(f"{stack.container}.{item}.")}
        )
        word = f"{item} ({', '.join(children)})" if children and item not in stack.inner else item
        separator = " | " if layer.independent else " " if layer.unlayered else " : "
        words.append((separator if n or layer.unlayered else "") + word)
    return words


def number(value: float) -> str:
    """A coordinate as the file writes it: at most one decimal, the same text for the same value."""
    text = f"{value:.1f}"
    return text[:-2] if text.endswith(".0") else text


class Canvas:
    """The SVG elements of the picture, as text, in the order they are drawn."""

    def __init__(self) -> None:
        self.elements: list[str] = []

    def add(self, element: str) -> None:
        self.elements.append(element)

    def rect(self, x: float, y: float, w: float, h: float, css: str) -> None:
        self.add(f'<rect class="{css}" x="{number(x)}" y="{number(y)}" width="{number(w)}" height="{number(h)}"/>')

    def text(self, x: float, y: float, text: str, css: str) -> None:
        self.add(f'<text class="{css}" x="{number(x)}" y="{number(y)}">{escape(text)}</text>')

    def arrow(self, points: list[tuple[float, float]], colour: str, width: float, title: str) -> None:
        """A line through ``points`` with a head at the last one, which lies on a box's left or right side."""
        (x0, _), (x1, y1) = points[-2], points[-1]
        sign = 1 if x1 > x0 else -1
        head = [(x1, y1), (x1 - sign * 7, y1 - 3.5), (x1 - sign * 7, y1 + 3.5)]
        points = points[:-1] + [(x1 - sign * 6, y1)]
        line = " ".join(f"{number(x)},{number(y)}" for x, y in points)
        self.add(
            f"<g><title>{escape(title)}</title>"
            f'<polyline points="{line}" fill="none" stroke="{colour}" stroke-width="{number(width)}"/>'
            f'<polygon points="{" ".join(f"{number(x)},{number(y)}" for x, y in head)}" fill="{colour}"/></g>'
        )


def weight(edge: Edge) -> float:
    """The width of an edge's line: 1 for one import, growing slowly with their number."""
    return 1 + 0.6 * math.log2(len(edge.pairs))


def lanes(found: list[Edge], right: bool) -> dict[int, int]:
    """The lane of each source on one side, 0 next to the boxes.

    On the right (imports going down) a lower layer's lane is nearer the boxes: a line leaving a box to its
    lane then crosses no other lane, since every lane nearer the boxes starts further down.
    """
    sources = sorted({e.source for e in found if (e.down if right else not e.down)}, reverse=right)
    return {source: n for n, source in enumerate(sources)}


def draw_stack(
    canvas: Canvas, stack: Stack, modules: list[str], imports: set[tuple[str, str]], x: float, y: float, width: float
) -> float:
    """Draw a stack's boxes and arrows in the ``width`` pixels from (x, y) on; returns the height drawn."""
    layers, places = place(stack, modules)
    found = edges(layers, places, imports)
    right, left = lanes(found, True), lanes(found, False)
    box_x = x + (GAP + LANE * len(left) if left else 0)
    box_w = width - (box_x - x) - (GAP + LANE * len(right) if right else 0)

    # The ports: where each line meets a box's side. Lines in (nearest source first), then the line out.
    ports: dict[tuple[int, bool], list[tuple[str, int]]] = {}
    for e in sorted(found, key=lambda e: -e.source if e.down else e.source):
        ports.setdefault((e.target, e.down), []).append(("in", e.source))
    for e in found:
        side = ports.setdefault((e.source, e.down), [])
        if ("out", e.source) not in side:
            side.append(("out", e.source))

    # A layer that is one package with a contract of its own holds that package's stack.
    inners = [stack.inner.get(layer.items[0]) if len(layer.items) == 1 else None for layer in layers]
    heights, labels = [], []
    for i, (layer, inner) in enumerate(zip(layers, inners)):
        if inner is not None:
            labels.append([f"{layer.items[0]}: {len(inner.layers)} layers of its own"])
            content = LINE + PAD + measure(inner, modules, imports, box_w - 2 * PAD)
        else:
            labels.append(wrap(label_words(layer, stack, modules), box_w - 2 * PAD))
            content = LINE * len(labels[-1])
        lines = max(len(ports.get((i, True), [])), len(ports.get((i, False), [])))
        heights.append(max(content + 2 * PAD, (lines + 1) * PORT))

    tops = []
    top = y
    for i, layer in enumerate(layers):
        tops.append(top)
        canvas.rect(box_x, top, box_w, heights[i], "unlayered" if layer.unlayered else "box")
        for n, line in enumerate(labels[i]):
            canvas.text(box_x + PAD, top + PAD + 12 + n * LINE, line, "label")
        if inners[i] is not None:
            draw_stack(canvas, inners[i], modules, imports, box_x + PAD, top + 2 * PAD + LINE, box_w - 2 * PAD)
        top += heights[i] + GAP
    height = top - GAP - y

    def port(layer: int, down: bool, what: tuple[str, int]) -> tuple[float, float]:
        side = ports[(layer, down)]
        spacing = heights[layer] / (len(side) + 1)
        return (box_x + box_w if down else box_x), tops[layer] + spacing * (side.index(what) + 1)

    for e in found:
        n = (right if e.down else left)[e.source]
        lane = box_x + box_w + GAP + LANE * n if e.down else box_x - GAP - LANE * n
        sx, sy = port(e.source, e.down, ("out", e.source))
        tx, ty = port(e.target, e.down, ("in", e.source))
        title = f"{len(e.pairs)} import{'s' if len(e.pairs) > 1 else ''}:\n" + "\n".join(
            f"{a} → {b}" for a, b in e.pairs
        )
        canvas.arrow([(sx, sy), (lane, sy), (lane, ty), (tx, ty)], e.colour, weight(e), title)
    return height


def measure(stack: Stack, modules: list[str], imports: set[tuple[str, str]], width: float) -> float:
    """The height a stack takes when drawn ``width`` pixels wide."""
    return draw_stack(Canvas(), stack, modules, imports, 0, 0, width)


def draw(src: pathlib.Path, pyproject: pathlib.Path) -> str:
    """The picture of the layers of the package in the folder ``src``, as SVG text.

    Examples
    --------
    >>> svg = draw(ROOT / "src" / "hestore", ROOT / "pyproject.toml")
    >>> svg.startswith("<svg") and "<title>The layers of hestore: imports go down</title>" in svg
    True
    """
    stack = read_stack(pyproject)
    modules, imports = read_imports(src)
    canvas = Canvas()
    title = f"The layers of {src.name}: imports go down"
    canvas.text(PAD, 20, title, "title")
    height = draw_stack(canvas, stack, modules, imports, PAD, 34, WIDTH - 2 * PAD)
    legend = 34 + height + 22
    for n, (colour, text) in enumerate(
        [
            (GREY, "imports (the wider the line, the more of them; hover over it to list them)"),
            (RED, "an import the contract forbids (lint-imports fails)"),
            (ORANGE, "an import from or to a module in no layer"),
        ]
    ):
        canvas.add(
            f'<line x1="{PAD}" y1="{number(legend + 16 * n - 4)}" x2="{PAD + 24}" y2="{number(legend + 16 * n - 4)}" '
            f'stroke="{colour}" stroke-width="2"/>'
        )
        canvas.text(PAD + 32, legend + 16 * n, text, "legend")
    canvas.text(PAD, legend + 16 * 3 + 6, f"drawn by `{COMMAND}` from src/{src.name} and pyproject.toml", "legend")
    total = legend + 16 * 3 + 16
    style = (
        f".box{{fill:#f4f6f9;stroke:#8795a8}}.unlayered{{fill:#fff4e5;stroke:{ORANGE};stroke-dasharray:4 3}}"
        f".label{{font:{FONT_SIZE}px {FONT};fill:#1f2933}}.title{{font:bold 14px sans-serif;fill:#1f2933}}"
        f".legend{{font:11px sans-serif;fill:#3e4c59}}"
    )
    return "\n".join(
        [
            f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{number(total)}" '
            f'viewBox="0 0 {WIDTH} {number(total)}" role="img">',
            f"<title>{escape(title)}</title>",
            f"<style>{style}</style>",
            f'<rect width="{WIDTH}" height="{number(total)}" fill="#fff"/>',
            *canvas.elements,
            "</svg>",
            "",
        ]
    )


def current() -> str:
    """The picture the code in this repository draws now."""
    return draw(ROOT / "src" / "hestore", ROOT / "pyproject.toml")


def stale(picture: pathlib.Path | None = None) -> str | None:
    """Why ``picture`` (``docs/img/layers.svg``) is not the one the code draws now, or None if it is."""
    picture = picture or PICTURE
    shown = picture.relative_to(ROOT) if picture.is_relative_to(ROOT) else picture
    if not picture.is_file():
        return f"{shown} is missing: run `{COMMAND}` and commit it"
    if picture.read_bytes().replace(b"\r\n", b"\n") != current().encode("utf-8"):  # a checkout's line ends
        return f"{shown} is not what the code draws now (imports or layers changed): run `{COMMAND}` and commit it"
    return None


def on_pre_build(config: object) -> None:
    """The mkdocs hook: the build fails while the picture in the repository is out of date."""
    from mkdocs.exceptions import PluginError

    reason = stale()
    if reason is not None:
        raise PluginError(reason)


def main(argv: list[str]) -> int:
    if argv == ["--check"]:
        reason = stale()
        print(reason or f"{PICTURE.relative_to(ROOT)} is up to date")
        return 1 if reason else 0
    if argv:
        print(__doc__.split("\n", 1)[0], f"usage: {COMMAND} [--check]", sep="\n", file=sys.stderr)
        return 2
    PICTURE.parent.mkdir(exist_ok=True)
    PICTURE.write_bytes(current().encode("utf-8"))
    print(f"{PICTURE.relative_to(ROOT)}: {PICTURE.stat().st_size:,} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
