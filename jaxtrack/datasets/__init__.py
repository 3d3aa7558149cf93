"""jaxtrack.datasets."""
