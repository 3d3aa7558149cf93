"""jaxtrack.tuning."""
