"""activeperc_rl: TorchRL training of the mover and the looker (meta-evaluation and baselines)."""
