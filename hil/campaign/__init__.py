"""Campaigns: many seeded simulator runs on Dask distributed, results in SQLite, statistics
with confidence intervals (docs/campaigns.md; ``rprs campaign``)."""
