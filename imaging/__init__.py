"""ctdrill imaging package."""
