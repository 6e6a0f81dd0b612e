"""The gistools Processing algorithms, one module per group: each declares its parameters (choices and
defaults read from the library), makes one gistools call and returns the output dict.

base       the shared plumbing (GistoolsAlgorithm) and the library's choices and defaults
tiles      info, points                    rasters    dsm, dem, rasters
ground     ground (ground and noise classes)
heights    normalize, metrics, chm, fuels (heights above ground, cell metrics, canopy height, canopy fuels)
steps      ndsm, bands, breaklines, clip, density, classify (gistools.products.steps)
shrub      the whole chain (shrubchain)   aquifer    aquifer, aquiferquery
runway     runway                          structure  structure
travel     travel, search_plan (search and rescue: a walker's travel time, the search plan)
deliver    webmap, scene, mapbook (deliverables for field teams)
terrain    terrain, viewshed (slope, aspect, hillshade, ruggedness; what observers see)

declared   the algorithm of a command declared whole (gistools.parameters: its inputs, summary, page, group),
           made from the declaration: slope_classes

A new algorithm is a class in its group's module (the provider finds it there); a command declared whole needs
none. A new group is a module named in GROUPS below.
"""

from . import aquifer, deliver, ground, heights, rasters, runway, shrub, steps, structure, terrain, tiles, travel
from .base import GistoolsAlgorithm

GROUPS = (tiles, ground, heights, rasters, steps, shrub, aquifer, runway, structure, deliver, terrain, travel)


def _algorithms_of(module) -> tuple:
    """The algorithm classes a group's module defines (each names itself: ``_name``), in their order there."""
    return tuple(c for c in vars(module).values() if isinstance(c, type) and issubclass(c, GistoolsAlgorithm)
                 and c.__module__ == module.__name__ and "_name" in vars(c))


ALGORITHMS = tuple(cls for module in GROUPS for cls in _algorithms_of(module))


def _declared() -> tuple:
    """The algorithms of the commands declared whole, in the groups of the algorithms above."""
    from gistools.parameters import DECLARED

    from .declared import declared_algorithm

    groups = {a._group[1]: a._group for a in ALGORITHMS}
    return tuple(declared_algorithm(command, groups) for command in sorted(DECLARED))


ALGORITHMS = ALGORITHMS + _declared()
