-- rigmon fleet historian, schema version 4: the health message's speed-free indicators
-- (issue 35) and the departure test, as typed columns of `windows`, and their 1-minute
-- aggregates in `minutes`. Applied in place to a version 3 database: nullable columns
-- without default and NOT NULL columns with a constant default rewrite no rows; the rows
-- already stored read as without indicators, as their messages were. No CHECK constraint
-- is added (it would read every stored partition under an exclusive lock); the historian
-- writes the four values, scores, smoothed scores and thresholds each all or none.

ALTER TABLE windows
    -- the classifier channel's RMS (channel unit), crest factor, excess kurtosis and RMS in
    -- the resonance band (a quarter of the rig's low-pass to the low-pass), and the window's
    -- sample count
    ADD COLUMN indicator_rms                 real,
    ADD COLUMN indicator_crest               real,
    ADD COLUMN indicator_kurtosis            real,
    ADD COLUMN indicator_resonance           real,
    ADD COLUMN indicator_samples             integer,
    -- against the machine's healthy baseline (models carrying it): each indicator's score
    -- (spreads from the healthy median), its running median and its threshold
    ADD COLUMN departure_score_rms           real,
    ADD COLUMN departure_score_crest         real,
    ADD COLUMN departure_score_kurtosis      real,
    ADD COLUMN departure_score_resonance     real,
    ADD COLUMN departure_smoothed_rms        real,
    ADD COLUMN departure_smoothed_crest      real,
    ADD COLUMN departure_smoothed_kurtosis   real,
    ADD COLUMN departure_smoothed_resonance  real,
    ADD COLUMN departure_threshold_rms       real,
    ADD COLUMN departure_threshold_crest     real,
    ADD COLUMN departure_threshold_kurtosis  real,
    ADD COLUMN departure_threshold_resonance real,
    ADD COLUMN departure_leading             text,  -- rms, crest, kurtosis or resonance
    ADD COLUMN departure_excess              real,  -- its smoothed score - threshold
    ADD COLUMN departure_beyond_for          integer, -- consecutive windows beyond
    ADD COLUMN departed_since                timestamptz; -- departed (the state holds a fault)

ALTER TABLE minutes
    ADD COLUMN indicator_rms_sum       double precision NOT NULL DEFAULT 0,
    ADD COLUMN indicator_rms_max       real,
    ADD COLUMN indicator_crest_sum     double precision NOT NULL DEFAULT 0,
    ADD COLUMN indicator_crest_max     real,
    ADD COLUMN indicator_kurtosis_sum  double precision NOT NULL DEFAULT 0,
    ADD COLUMN indicator_kurtosis_max  real,
    ADD COLUMN indicator_resonance_sum double precision NOT NULL DEFAULT 0,
    ADD COLUMN indicator_resonance_max real,
    ADD COLUMN indicators_n            integer NOT NULL DEFAULT 0,
    ADD COLUMN departed_windows        integer NOT NULL DEFAULT 0;

CREATE OR REPLACE VIEW minute_means AS
SELECT point_id, minute, windows, bad_quality, unknown_windows, fault_windows, last_state,
       rpm_sum / NULLIF(rpm_n, 0) AS rpm,
       velocity_sum / NULLIF(velocity_n, 0) AS velocity_rms_mm_s, velocity_max,
       bpfo_1_sum / NULLIF(bands_n, 0) AS bpfo_1, bpfo_1_max,
       bpfi_1_sum / NULLIF(bands_n, 0) AS bpfi_1, bpfi_1_max,
       two_bsf_1_sum / NULLIF(bands_n, 0) AS two_bsf_1, two_bsf_1_max,
       novelty_max,
       indicator_rms_sum / NULLIF(indicators_n, 0) AS indicator_rms, indicator_rms_max,
       indicator_crest_sum / NULLIF(indicators_n, 0) AS indicator_crest, indicator_crest_max,
       indicator_kurtosis_sum / NULLIF(indicators_n, 0) AS indicator_kurtosis,
       indicator_kurtosis_max,
       indicator_resonance_sum / NULLIF(indicators_n, 0) AS indicator_resonance,
       indicator_resonance_max,
       departed_windows
FROM minutes;
