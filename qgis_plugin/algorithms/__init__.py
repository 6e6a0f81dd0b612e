"""The gistools Processing algorithms, one module per group: each declares its parameters (choices and
defaults read from the library), makes one gistools call and returns the output dict.

base       the shared plumbing (GistoolsAlgorithm) and the library's choices and defaults
tiles      info, points                    rasters    dsm, dem, rasters
ground     ground (ground and noise classes)
heights    normalize, metrics, chm, fuels (heights above ground, cell metrics, canopy height, canopy fuels)
steps      ndsm, bands, breaklines, clip, density, classify (gistools.products.steps)
shrub      the whole chain (shrubchain)   aquifer    aquifer, aquiferquery
runway     runway                          structure  structure
travel     travel (search and rescue: a walker's travel time)
deliver    webmap, scene, mapbook (deliverables for field teams)
terrain    terrain, viewshed (slope, aspect, hillshade, ruggedness; what observers see)

declared   the algorithm of a command declared whole (gistools.parameters: its inputs, summary, page, group),
           made from the declaration: slope_classes

A new algorithm goes in its group's module and into ALGORITHMS below; a command declared whole needs neither.
"""

from .aquifer import AquiferModelAlgorithm, AquiferQueryAlgorithm
from .deliver import MapBookAlgorithm, SceneAlgorithm, WebMapAlgorithm
from .ground import GroundAlgorithm
from .heights import ChmAlgorithm, FuelsAlgorithm, MetricsAlgorithm, NormalizeAlgorithm
from .rasters import DemAlgorithm, DsmAlgorithm, RastersAlgorithm
from .runway import RunwayAlgorithm
from .shrub import ShrubChainAlgorithm
from .steps import BandsAlgorithm, BreaklinesAlgorithm, ClassifyAlgorithm, ClipAlgorithm, DensityAlgorithm, NdsmAlgorithm
from .structure import StructureAlgorithm
from .terrain import TerrainAlgorithm, ViewshedAlgorithm
from .tiles import InfoAlgorithm, PointsAlgorithm
from .travel import TravelAlgorithm

ALGORITHMS = (InfoAlgorithm, PointsAlgorithm, GroundAlgorithm, NormalizeAlgorithm, MetricsAlgorithm, ChmAlgorithm, FuelsAlgorithm, DsmAlgorithm, DemAlgorithm, NdsmAlgorithm, RastersAlgorithm, BandsAlgorithm,
              BreaklinesAlgorithm, ClipAlgorithm, DensityAlgorithm, ClassifyAlgorithm, ShrubChainAlgorithm,
              AquiferModelAlgorithm, AquiferQueryAlgorithm, RunwayAlgorithm, StructureAlgorithm, WebMapAlgorithm,
              SceneAlgorithm, MapBookAlgorithm, TerrainAlgorithm, ViewshedAlgorithm,
              TravelAlgorithm)


def _declared() -> tuple:
    """The algorithms of the commands declared whole, in the groups of the algorithms above."""
    from gistools.parameters import DECLARED

    from .declared import declared_algorithm

    groups = {a._group[1]: a._group for a in ALGORITHMS}
    return tuple(declared_algorithm(command, groups) for command in sorted(DECLARED))


ALGORITHMS = ALGORITHMS + _declared()
