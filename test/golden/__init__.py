"""Golden replay outputs (CSV) and the table of cases that produces them (:mod:`.cases`)."""
