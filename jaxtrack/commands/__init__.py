"""Sub-commands of the jaxtrack CLI; each module defines ``register(subparsers)``."""
