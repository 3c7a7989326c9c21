"""The pure-numpy world: scenarios, crowd, radio model and rasters (no PettingZoo, torch or drawing)."""
