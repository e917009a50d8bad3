"""The atlas build's search for dwell segments of coupler curves (:mod:`~synth.segment_search.segments`):
candidates from curvature theory, measured on the exact path with minimum-zone fits, merged, and
bounded for the query (:mod:`~synth.segment_search.dwell_bounds`, :mod:`~synth.segment_search.dwell_key`).
No re-exports: ``dwell --help`` would pay for these imports.
"""
