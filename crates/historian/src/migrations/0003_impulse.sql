-- rigmon fleet historian, schema version 3: a window's class can be decided by an impulsive
-- signal (`decision` = 'impulsive', the classifier's `healthy` overruled), and the
-- impulsiveness the verdict used is stored: how many standard deviations the classifier
-- channel's excess kurtosis (mean over the last windows) stands above the machine's healthy
-- windows and above Gaussian noise (aligned models carrying the kurtosis baseline only; both
-- or none). Applied in place to a version 2 database; the rows already stored read as
-- without impulsiveness, as their messages were.

ALTER TABLE windows
    DROP CONSTRAINT windows_decision_check,
    ADD CONSTRAINT windows_decision_check
        CHECK (decision IN ('model', 'confirmed', 'evidence', 'impulsive')),
    ADD COLUMN impulse_beyond_healthy  real,
    ADD COLUMN impulse_beyond_gaussian real,
    ADD CONSTRAINT windows_impulse_whole CHECK (
        (impulse_beyond_healthy IS NULL) = (impulse_beyond_gaussian IS NULL));
