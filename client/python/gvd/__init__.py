"""gvd: a client for gvd-server, which computes generalized Voronoi diagrams on graphics
hardware and answers proximity queries.

    import numpy as np, gvd
    with gvd.Client("127.0.0.1:50051") as c:          # "http://127.0.0.1:8080": HTTP
        c.create_scene("s", window=(0, 0, 1, 1), size=(1024, 1024))
        v = c.upsert_points("s", ids, xy)             # xy: (n, 2) array
        r = c.find_nearest("s", q, min_version=v)     # q: (m, 2) array
        r.site_ids, r.distances, r.error_bounds, r.exact
        c.upsert_sites("s", gvd.sites_from_svg("drawing.svg"))  # a path site per element

Errors are GvdError (code: a grpc.StatusCode; message: the server's). The API's messages
are gvd.v1 (generated from the server's proto when the package is built).
"""
from ._client import AsyncClient, Client, NearestResult, Path, Raster, site_from_dict
from ._svg import sites_from_svg
from ._transport import GvdError

__all__ = ["AsyncClient", "Client", "GvdError", "NearestResult", "Path", "Raster", "site_from_dict",
           "sites_from_svg"]
__version__ = "0.1.0"
