"""Studies: study files, parallel cached sweeps (dask) and their table. Maps a simulation over
designs and never reaches inside one."""
