"""Benchmarks of the service: ``pdr bench server|load|faults|processor`` and the local scale-out deployment they
start (:mod:`~server.bench.cluster`). The service itself never imports this package.
"""
