"""Dyno test campaigns: which tests to run next on a damper.

  planning.py   tests planned where a model is unsure (`dampnet plan-tests`): the drives a
                controller's roads put outside the training envelope, ranked by what they add
  replay.py     track-replay tests: a quarter car's damper stroke over a registry road under a
                control law, as the rig's drive (`dampnet rig --replay`)
"""
