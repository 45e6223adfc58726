# Adaptive octree FMM: tree, lists, expansions, plane-wave M2L, driver.
