"""One router per resource: health, experiments, runs, individuals."""
