"""Running experiments: what a request may cost (``limits``), turning treatments into stored
runs (``submit``), the coordinator that drives each run's generations (``coordinator``,
``driver``), the executors that hand evaluations to workers behind one protocol
(``executors``: local processes; ``rq_executor``: Redis + RQ) and the locks that keep two
coordinators off one run (``locks``)."""
