"""Sweeps and hyperparameter search on Ray Tune (``bulletnav sweep``): the sweep file
(:mod:`.spec`), the trials (:mod:`.run`) and their table (:mod:`.results`)."""
