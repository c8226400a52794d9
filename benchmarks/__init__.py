"""Benchmark scripts: each runs as a module from the repository root, ``python -m benchmarks.<name> --help``
(``benchmarks/README.md`` lists them). They are not part of the installed package."""
