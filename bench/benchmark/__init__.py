"""PlateBench as a benchmark: a frozen, versioned split, its protocol, and the leaderboard.

``split``: the split's definition (a TOML file per version in ``splits/``) and its expansion into
samples; ``build``: the split rendered with the sweep machinery, then ``verify``-ed against the
ground-truth checksums shipped beside its definition; ``score``: a method run by the bench, or a
folder of another program's outputs, scored by the protocol (``platebench.evaluation.protocol``)
into one results table; ``leaderboard``: tables and pages from one or more results folders.
The protocol is written out in ``docs/benchmark.md``.
"""
