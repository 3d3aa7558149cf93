"""jaxtrack.association."""
