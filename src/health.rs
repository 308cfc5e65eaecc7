//! Health state machine: per-window results -> smoothed state with hysteresis; the health message. (owner: daemon)
