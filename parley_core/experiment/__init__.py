"""Campaigns: many instances x repetitions, a resumable SQLite store, local or Dask execution,
and reports (the paper's Tables 2 and 3, Fig. 4)."""
