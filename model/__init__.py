"""ctdrill model package."""
