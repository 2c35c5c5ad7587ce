"""Reports of stored experiments: the report files ``softevo report`` writes (``report``) and
the experiment page's tables and figures (``experiment``), both read from storage and drawn
by ``analysis``."""
