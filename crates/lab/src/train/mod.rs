//! Training beside the stream: recordings of a [`crate::manifest`] featurised ([`dataset`],
//! [`featurise`]), splits by recording ([`split`]), the optimiser loop ([`trainer`]), and
//! turning a training run into a complete model with novelty calibration and metadata
//! ([`fit`]); fine-tuning on measured recordings ([`finetune`]); whole-record scoring of a
//! model file and of the rule baseline on a manifest ([`score`]).

pub mod dataset;
pub mod featurise;
pub mod finetune;
pub mod fit;
pub mod score;
pub mod split;
pub mod trainer;
