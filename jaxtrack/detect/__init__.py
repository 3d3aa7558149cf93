"""jaxtrack.detect."""
