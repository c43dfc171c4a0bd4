"""Files and xarray contracts: atomic writes, staged run folders, the trajectory contract."""
