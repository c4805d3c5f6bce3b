"""Shared leaf utilities: errors, paths, the EXR reader and writer, image
metrics, regions, display encoding and the region classes' style.

Imports nothing of the harness outside core/ (the bottom layer:
core <- experiment <- execution, reference <- analysis <- figures <- service, viewer, cli)."""
