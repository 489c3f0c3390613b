"""Component catalogs: datasheet tables read, validated and converted to SI, and the data
the package ships.

The bottom floor of ``optimizer``: it knows no model, solver or flight. Modules, one job
each: ``catalog`` (a catalog folder or frames -> ``Catalog``; datasheet units live only
here), ``model_constants`` (a catalog's ``catalog.toml``: the open readings of the printed
equations), ``sizinglab`` (the SizingLab open data imported as a catalog), ``freeform``
(a one-design catalog from datasheet numbers typed by the user) and ``shipped_data``
(where the shipped catalogs and data live, found with ``importlib.resources``).
"""
