"""What several notebooks share: caches, families, maps, the protocol, comparisons, results, the claims ledger.

See :mod:`prodmaps.experiments` for the list. Importing this package imports nothing.
"""
