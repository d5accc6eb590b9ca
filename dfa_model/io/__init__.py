"""Data in and out: parameter files, protocol files, recordings, results, plots, atomic
file writing, state serialization, synthetic datasets."""
