"""jaxtrack.context."""
