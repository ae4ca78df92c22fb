"""ctdrill haptics package."""
