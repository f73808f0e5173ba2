# SPDX-License-Identifier: GPL-3.0-or-later
"""Where the nodes of a generated tree go (bpy-free): labelled frames of at most FRAME_MAX
nodes, side by side, each laid out in columns by the order of dependency.

A node is a box: its width and height (see :func:`node_height`) at a location, its top-left
corner (Blender's convention: y grows upwards, a node hangs down from its location).  The
layout never lets two boxes overlap: columns are as wide as their widest node plus a gap,
nodes in a column are stacked with a gap, frames are placed after the previous frame's right
edge."""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ("FRAME_MAX", "Box", "Frame", "chunks", "layout", "node_height", "overlaps")

#: The most nodes one frame holds (a section with more is split into numbered frames).
FRAME_MAX = 80
COLUMN_GAP = 60.0
ROW_GAP = 20.0
FRAME_GAP = 160.0
#: Space the frame's label takes above its first node, and the frame's margin.
FRAME_LABEL = 60.0
FRAME_MARGIN = 30.0

#: Rows of a node's own controls drawn between its header and its sockets (its properties).
_PROPERTY_ROWS = {"ShaderNodeMath": 2, "ShaderNodeVectorMath": 1, "ShaderNodeMix": 3,
                  "ShaderNodeClamp": 1, "ShaderNodeSeparateColor": 1,
                  "ShaderNodeCombineColor": 1, "ShaderNodeValToRGB": 6,
                  "ShaderNodeTexEnvironment": 6, "ShaderNodeBsdfPrincipled": 6,
                  "ShaderNodeBsdfMetallic": 2, "ShaderNodeBsdfGlossy": 1,
                  "ShaderNodeMixShader": 0, "ShaderNodeAddShader": 0, "NodeGroupInput": 0,
                  "NodeGroupOutput": 0, "ShaderNodeLayerWeight": 0}
_HEADER = 40.0
_ROW = 24.0


def node_height(bl_idname, socket_rows):
    """A node's height in the editor at UI scale 1: its header, its property rows and
    ``socket_rows`` rows of sockets (an unlinked vector input draws 4: its label and x, y, z).
    An over-estimate by design (a few pixels per row), so that boxes that do not overlap here
    do not overlap on screen."""
    return _HEADER + _ROW * (_PROPERTY_ROWS.get(bl_idname, 4) + socket_rows)


@dataclass
class Box:
    """A node to place: ``key`` identifies it, ``depth`` orders columns (a node's inputs come
    from smaller depths), ``width`` and ``height`` its size."""

    key: object
    depth: int
    width: float
    height: float
    x: float = 0.0
    y: float = 0.0


@dataclass
class Frame:
    """A labelled frame around ``boxes`` (placed by :func:`layout`): ``x``, ``y`` its top-left,
    ``width``, ``height`` its extent."""

    title: str
    boxes: list = field(default_factory=list)
    x: float = 0.0
    y: float = 0.0
    width: float = 0.0
    height: float = 0.0


def chunks(title, boxes, limit=FRAME_MAX):
    """``boxes`` in frames of at most ``limit``, in order of depth (a long section becomes
    "title (1/3)", "title (2/3)", ...)."""
    boxes = sorted(boxes, key=lambda b: b.depth)
    n = max(1, -(-len(boxes) // limit))
    if n == 1:
        return [Frame(title, boxes)]
    return [Frame(f"{title} ({i + 1}/{n})", boxes[i * limit:(i + 1) * limit]) for i in range(n)]


def _place_frame(frame, x0, y0):
    """Columns by depth (the depths the frame uses, in order), nodes stacked in each."""
    depths = sorted({b.depth for b in frame.boxes})
    cols = {d: [b for b in frame.boxes if b.depth == d] for d in depths}
    x = x0 + FRAME_MARGIN
    bottom = y0 - FRAME_LABEL
    for d in depths:
        width = max(b.width for b in cols[d])
        y = y0 - FRAME_LABEL
        for b in cols[d]:
            b.x, b.y = x, y
            y -= b.height + ROW_GAP
        bottom = min(bottom, y)
        x += width + COLUMN_GAP
    frame.x, frame.y = x0, y0
    frame.width = x - x0 - COLUMN_GAP + FRAME_MARGIN
    frame.height = y0 - bottom + FRAME_MARGIN


def layout(frames, x0=0.0, y0=0.0):
    """Place ``frames`` left to right from (x0, y0) (top edges aligned).  Returns the x after
    the last frame."""
    x = x0
    for frame in frames:
        _place_frame(frame, x, y0)
        x += frame.width + FRAME_GAP
    return x


def overlaps(rects):
    """The pairs of (key, x, y, width, height) rectangles (top-left corners, y up) that
    overlap."""
    out = []
    items = sorted(rects, key=lambda r: r[1])
    for i, a in enumerate(items):
        for b in items[i + 1:]:
            if b[1] >= a[1] + a[3]:
                break
            if b[2] - b[4] < a[2] and a[2] - a[4] < b[2]:
                out.append((a[0], b[0]))
    return out
