"""The diagnosis's rules: which candidates a round tries (:mod:`.selection_rules`), when the search stops
(:mod:`.stopping_rules`) and the robust test that adopts an effect (:mod:`.robust_test`)."""
