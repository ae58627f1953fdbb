"""CLI subcommands, one module each. A module defines ``register(subparsers)`` which adds its parser
and sets ``func`` (taking the parsed args, returning an exit code). The CLI discovers modules here,
so adding a command touches no shared file."""
