-- rigmon fleet historian, schema version 2: the health message's fields added after version 1
-- (what decided the window's class, the fault-family evidence, how sure the speed tracker
-- is, a foreign model's differences), as typed columns of `windows`. Applied in place to a
-- version 1 database: the new columns are added to the partitioned parent (every partition
-- gets them); adding a column with a constant default rewrites nothing, and the rows already
-- stored read as decided by the model with the other fields absent, as their messages were.

ALTER TABLE windows
    -- model (the classifier), confirmed (its fault family's bins beyond the healthy level),
    -- evidence (the fault family the spectrum points at, overruling the classifier)
    ADD COLUMN decision            text NOT NULL DEFAULT 'model'
        CONSTRAINT windows_decision_check CHECK (decision IN ('model', 'confirmed', 'evidence')),
    ADD COLUMN overruled           text,              -- the classifier's class it overruled
    -- standard deviations each fault family's bins stand above the machine's healthy level
    -- (aligned models only; all three or none)
    ADD COLUMN evidence_outer_race real,
    ADD COLUMN evidence_inner_race real,
    ADD COLUMN evidence_ball       real,
    ADD COLUMN speed_confidence    real,              -- speed read from the vibration: 0-1
    ADD COLUMN speed_rival_rpm     double precision,  -- half or twice it, nearly as likely
    ADD COLUMN model_foreign       text[],            -- how an allowed foreign model differs
    ADD CONSTRAINT windows_evidence_whole CHECK (
        (evidence_outer_race IS NULL) = (evidence_inner_race IS NULL)
        AND (evidence_inner_race IS NULL) = (evidence_ball IS NULL));
