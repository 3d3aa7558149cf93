"""jaxtrack.filters."""
