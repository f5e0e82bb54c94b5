"""The run machinery around the algorithm: run directories (:mod:`.rundir`), checkpoints and exact resume
(:mod:`.checkpoint`), files written whole (:mod:`.atomic`), stop signals (:mod:`.signals`), portable mode
(:mod:`.portable`) and the allocator's settings (:mod:`.allocator`)."""
