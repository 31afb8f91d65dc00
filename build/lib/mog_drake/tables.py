"""Plain-text tables for the terminal."""

from __future__ import annotations


def _fmt(v) -> str:
    if isinstance(v, float):
        if v != v:  # nan
            return "-"
        return f"{v:.4g}" if abs(v) < 1e4 else f"{v:.0f}"
    if v is None:
        return "-"
    return str(v)


def format_table(rows: list[dict], columns: list[str] | None = None, headers: dict | None = None) -> str:
    """Formats dict rows as an aligned text table (columns in the given order)."""
    if not rows:
        return "(no rows)"
    columns = columns or list(rows[0])
    headers = headers or {}
    cells = [[headers.get(c, c) for c in columns]] + [[_fmt(r.get(c)) for c in columns] for r in rows]
    widths = [max(len(row[j]) for row in cells) for j in range(len(columns))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
