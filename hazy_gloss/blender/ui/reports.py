# SPDX-License-Identifier: GPL-3.0-or-later
"""How an operator reports: to Blender (``op.report``) and to :data:`last_reports` (tests,
scripts).  Every operator module reports through here, so none imports another's."""

__all__ = ("last_reports", "report", "finish")

#: (level, message) of every report, newest last (kept short).
last_reports = []


def report(op, level, message):
    op.report({level}, message)
    last_reports.append((level, message))
    del last_reports[:-50]


def finish(op, status, msg, notes):
    """An operator's return value for an action's (status, message, notes), reported."""
    if status == "ERROR":
        report(op, "ERROR", msg)
        return {"CANCELLED"}
    report(op, "INFO", msg)
    if notes:
        report(op, "WARNING", "; ".join(n[:1].upper() + n[1:] for n in notes))
    return {"FINISHED"} if status == "FINISHED" else {"CANCELLED"}
