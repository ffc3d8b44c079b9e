"""Danger-area outlines and maps for a site plan (docs/hazard.md, "Outlines and GIS files"): needs the
gis extra (shapely, pyproj, rasterio); `warp-ricochet export`."""

GIS_EXTRA = "pip install 'warp-ricochet[gis]'"
