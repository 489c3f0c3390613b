"""User-facing errors of the optimizer (catalogs, requests)."""


class CatalogError(ValueError):
    """A catalog file is invalid; the message names the file, row and column."""

    exit_code = 2


class RequestError(ValueError):
    """An optimization request is invalid (unknown id, bad objective, bad bound)."""

    exit_code = 2
