"""Scenario runner (launchless, lockstep or real time), MCAP recorder, replay, analysis and plots
for the catheter node graph."""
