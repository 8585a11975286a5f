"""Files and names: the one resolver of preset names and paths into model objects, and the CSV reader/writer."""
