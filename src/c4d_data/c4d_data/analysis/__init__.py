"""Flight analysis: data extraction from a recording, plots, HTML report."""
