"""The run: the pipeline, its stages and tasks, helper processes, the output folder, stage files."""
