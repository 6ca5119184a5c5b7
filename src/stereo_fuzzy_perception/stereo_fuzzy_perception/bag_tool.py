"""Placeholder: implemented with the scenes-and-bags issue."""


def main() -> None:
    """Exit with a message until implemented."""
    raise SystemExit('not implemented yet')
