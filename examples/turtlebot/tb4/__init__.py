"""The TurtleBot 4 occlusion demonstrator's own code, split by concern.

Managed system (the simulated robot): :mod:`.geometry` (shapes and ray casting), :mod:`.world`
(maps and scenarios), :mod:`.lidar` (the 360-ray scanner with debris), :mod:`.navigation` (local
costmap, local planner and the spin-inserting controller) and :mod:`.simulator`.

Managing system (the MAPLE-K stages use these): :mod:`.occlusion` (per-angle occlusion
probability and clustering), :mod:`.spin` (spin plans that bring occluded sectors into view) and
:mod:`.legitimacy` (inline simulation of a plan on the current map).
"""
