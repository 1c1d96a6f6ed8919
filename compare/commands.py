"""CLI subcommands of this package (registered by pbrcheck.cli)."""


def register(sub, bench_sub) -> None:
    """Add this package's subcommands to the ``pbrcheck`` parser."""
