"""MHM, the Multiple Hinged Method of Mukhija, Krishna and Krishna (two-phase recursive tree propagation with a
fixed base station constraint): the geometry of the Exploration Wavefront (``wavefront``), the exploration
tree with parent choice and tree breaking (``tree``), phase 2's chain (``chain``), the explorers' moves
(``explore``), and the base station's planner that runs section III-D's steps tick by tick (``planner``), all
pure; the base's orders on the radio (``orders``), the base process's planner hook (``station``), and the
``mhm`` allocator that obeys them in each robot (``robot``).
"""
