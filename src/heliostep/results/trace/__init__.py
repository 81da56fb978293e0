"""The trace: its columns and metadata (`frame`), its files (`files`, `format`, `writer`, `stream`,
`modelica`) and the row sinks (`sinks`)."""
