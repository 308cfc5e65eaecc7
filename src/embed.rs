//! 2-D embeddings (t-SNE / PCA) of feature windows coloured by class and domain. (owner: training)
