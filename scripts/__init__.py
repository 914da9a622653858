"""Command-line scripts (train, evaluate, render); `scripts._cli` holds what they share."""
