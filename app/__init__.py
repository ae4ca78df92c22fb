"""ctdrill app package."""
