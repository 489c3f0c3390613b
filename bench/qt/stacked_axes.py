"""The axes of one plot in a stack of plots that share their time axis.

Axis text dominated a frame on the offscreen platform (the live view: 41 of 43 ms for its
eight axes, redrawn every frame; benchmarks/live_frame.py). So a stack shows its time axis
once, and every axis is kept as a pixmap while its range stands. The live view and the
console's plots both lay out their stacks so.
"""

from __future__ import annotations

from typing import Any

__all__ = ["stacked_axes"]


def stacked_axes(plot: Any, time_label: tuple[str, str] | None) -> tuple[Any, Any]:
    """Hide ``plot``'s bottom axis, or label it ``(text, units)`` where the stack shows
    its time; cache the left and bottom axes. Returns them (left, bottom)."""
    from pyqtgraph.Qt import QtWidgets

    if time_label is None:
        plot.hideAxis("bottom")
    else:
        plot.setLabel("bottom", time_label[0], units=time_label[1])
    axes = plot.getAxis("left"), plot.getAxis("bottom")
    for axis in axes:
        axis.setCacheMode(QtWidgets.QGraphicsItem.CacheMode.DeviceCoordinateCache)
    return axes
