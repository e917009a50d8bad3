"""The six-bar: a four-bar whose coupler point drives an output dyad, its exact simulation
(:mod:`~synth.mechanism.sixbar`), the windowed range of its output (:mod:`~synth.mechanism.output_range`),
what a user is shown about it (:mod:`~synth.mechanism.figures`, :mod:`~synth.mechanism.buildability`,
:mod:`~synth.mechanism.tolerance`) and the output dyads fitted to a dwell segment
(:mod:`~synth.mechanism.dyad`). No re-exports: the public names are in :mod:`synth`.
"""
