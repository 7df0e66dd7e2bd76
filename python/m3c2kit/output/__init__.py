"""What a run writes and prints besides the engine's numbers (docs/architecture.md): the point
table (writing), the summary, the expected false-positive rate of the LOD, the HTML report and
its figures (report/)."""
