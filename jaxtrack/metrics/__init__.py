"""jaxtrack.metrics."""
