//! Whole-record scoring of a classifier on labelled recordings: accuracy, balanced accuracy, confusion matrix. (owner: training)
