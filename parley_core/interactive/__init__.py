"""Interactive, self-contained HTML reports (Bokeh standalone documents): a run's
``report.html`` (:mod:`.run_page`) and a campaign's (:mod:`.campaign_page`)."""
