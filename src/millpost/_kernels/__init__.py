"""Compiled (numba) inner loops. Each module is an implementation detail of a public module:
`raster` of `millpost.stock.mesh`, `engage` of `millpost.engagement`."""
