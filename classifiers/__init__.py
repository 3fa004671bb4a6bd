"""Motion-mode, placement and landmark classifiers: features, estimators, training and evaluation."""
