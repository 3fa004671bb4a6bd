"""The building as an input: floor plans of a site (walkable areas, walls, floor altitudes, north).

:mod:`pdr.site.plan` reads and validates the ``floors`` section of a site description (the landmark section is
:class:`pdr.phone.landmarks.Site`), :mod:`pdr.site.geometry` holds the vectorised polygon and segment tests,
:mod:`pdr.site.wall_index` the grid of wall segments the map matcher queries, :mod:`pdr.site.ms` builds a site
from a Microsoft Indoor Location floor folder.
"""
