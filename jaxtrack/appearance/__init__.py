"""jaxtrack.appearance."""
