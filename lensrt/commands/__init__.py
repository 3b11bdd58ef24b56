"""CLI subcommands; each module defines ``register(subparsers)``. Imports inside functions stay lazy."""
