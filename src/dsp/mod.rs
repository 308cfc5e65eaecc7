//! Feature pipeline: low-pass, Hilbert envelope, computed order tracking from the tacho,
//! order spectrum, RMS per order bin. Plans and buffers are made once and reused.
