"""Controllers in closed loop: a policy in Storm's simulator (:mod:`.storm`), missions sampled
from a policy's DTMC (:mod:`.missions`), fixed and adaptive URCs under a drifting model
(:mod:`.drift`, :mod:`.drift_report`), and a run's policies on the plugin's own simulator
(:mod:`.validate`)."""
