"""Trained weights of the view classifier (package data, loaded by carbody.view.predict)."""
