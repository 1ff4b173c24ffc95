"""The benchmark: every controller on the same seeded episodes of every world, scored by one
metrics module, written as ``results.json`` and a static ``report.html``
(``bulletnav benchmark SUITE``).

- :mod:`bulletnav.benchmark.suite`: suite files (worlds, controllers, episodes, seed);
- :mod:`bulletnav.benchmark.metrics`: every metric, defined once, with 95 % bootstrap intervals;
- :mod:`bulletnav.benchmark.runner`: parallel, resumable runs with the same rows at any worker count;
- :mod:`bulletnav.benchmark.report`: the self-contained HTML report.
"""
