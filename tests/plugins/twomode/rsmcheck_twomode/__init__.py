"""rsmcheck-twomode: an engine plug-in for rsmcheck (docs/plugins.md, the worked example).

The engine is the reference model at the paper's two eigenmodes per link, without the
static correction shapes of docs/physics.md §2.4: the model the paper describes, run beside
the reference to show what the static shapes change.
"""
