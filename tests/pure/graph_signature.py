# SPDX-License-Identifier: GPL-3.0-or-later
"""The structure of a core.graph computation, for tests that compare two graphs: operations and
wiring of the nodes some outputs need, not their constant values (two graphs with the same
signature emit the same nodes)."""


def _flatten(outputs):
    if isinstance(outputs, dict):
        outputs = list(outputs.values())
    if not isinstance(outputs, (list, tuple)):
        return [outputs]
    return [x for o in outputs for x in _flatten(o)]


def signature(g, outputs):
    """A hash of the nodes of ``g`` that ``outputs`` (an Expr, or dicts / lists of them) need."""
    order = g.used(outputs)
    pos = {e.index: i for i, e in enumerate(order)}
    rows = []
    for e in order:
        args = tuple(("c", a.vector) if a.is_const else pos[a.index] for a in e.args)
        rows.append((e.op, e.name, e.vector, e.clamp, e.lane, args,
                     len(e.value) if e.op == "RAMP" else None))
    outs = tuple(("c",) if e.is_const else pos[e.index]
                 for e in _flatten(outputs) if hasattr(e, "is_const"))
    return hash((tuple(rows), outs))
