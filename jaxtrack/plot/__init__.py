"""jaxtrack.plot."""
