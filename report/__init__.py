"""Export of results: tables, JSON, plots, drawings (HTML reports come with the query stage)."""

from report.drawing import Sketch, draw_sketch
from report.motion_table import Column, MotionTable, unit_key
from report.plots import plot_motion

__all__ = ["Column", "MotionTable", "Sketch", "draw_sketch", "plot_motion", "unit_key"]
