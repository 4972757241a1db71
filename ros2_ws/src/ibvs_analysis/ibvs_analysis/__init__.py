"""What a run's bag says: metrics, success, figures, the film, and its results written."""
