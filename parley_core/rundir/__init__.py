"""The run directory: written from a run (:mod:`.write`), its summary.json record
(:mod:`.summary`), read back as value objects (:mod:`.read`), its policies files
(:mod:`.policies`), its report.html (:mod:`.page`, :mod:`.policy_grid`), and a policy chosen
from it as a controller (:mod:`.select`). Everything but the writer reads the files alone."""
