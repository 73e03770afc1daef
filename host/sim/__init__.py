"""The simulated rig: motion-blurred rope frames with exact ground truth, written as frame sets.

Public API
----------
* `ropecam.host.sim.presets.preset(name)` -> `SimConfig` (``paper``, ``paper-soft``, ``rig``, ``rig-soft``);
  `ropecam.host.sim.config.merge_overrides(config, mapping)` changes any field (TOML tables, validated).
  `SimConfig.rope` and `SimConfig.solver` are the ANCF model's `RopeConfig` and `SolverConfig`.
* `ropecam.host.sim.dynamics.solve_trajectory(config)` -> `Trajectory`: the ANCF model run with `config.rope` and
  `config.model_solver()` (the solver, its duration extended to cover the last exposure).
* `ropecam.host.sim.generate.write_frameset(config, trajectory, out, exposure_ms)` -> `SetSummary`, and
  `write_framesets(config, trajectory, out)` for every exposure of a configuration.
* `ropecam.host.sim.render.RopeRenderer` (one exposure's coverage images) and `ropecam.host.sim.scene`
  (`build_scene`, `Sensor`) for callers composing frames themselves.

The format is documented in docs/frameset.md, the simulator in docs/simulator.md.
"""
