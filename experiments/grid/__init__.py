"""The grid engine's data: a cell as typed data (``spec``: ``Method``, ``CellSpec``)."""
