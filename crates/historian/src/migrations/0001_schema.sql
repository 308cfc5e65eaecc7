-- rigmon fleet historian, schema version 1 (applied by `rigmon historian` on start).
-- The asset tree (site / machine / asset / point from each rig file), one row per window with
-- typed columns, 1-minute aggregates, state-change events (alarms) with the full health JSON,
-- the latest window and daemon status per point. `windows` and `minutes` are partitioned by
-- time (daily / monthly partitions made on demand, dropped past their retention).

CREATE TABLE sites (
    site_id    integer GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
    name       text NOT NULL UNIQUE
);

CREATE TABLE machines (
    machine_id integer GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
    site_id    integer NOT NULL REFERENCES sites,
    name       text NOT NULL UNIQUE              -- the rig file's [machine] id
);

CREATE TABLE assets (
    asset_id   integer GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
    machine_id integer NOT NULL REFERENCES machines,
    name       text NOT NULL,
    UNIQUE (machine_id, name)
);

CREATE TABLE points (
    point_id         integer GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
    asset_id         integer NOT NULL REFERENCES assets,
    name             text NOT NULL,
    key              text NOT NULL UNIQUE,     -- <machine>/<asset>/<point>, as on Zenoh
    first_seen       timestamptz NOT NULL DEFAULT now(),
    band_channel     text,                     -- channel the fault bands come from
    band_orders      jsonb,                    -- fault orders (bpfo, bpfi, two_bsf)
    calibration_id   text,
    software_version text,
    iso_limits_mm_s  real[],                   -- ISO 20816-3 zone limits A/B, B/C, C/D
    UNIQUE (asset_id, name)
);

CREATE VIEW asset_tree AS
SELECT s.name AS site, m.name AS machine, a.name AS asset, p.name AS point, p.point_id, p.key
FROM points p
JOIN assets a USING (asset_id)
JOIN machines m USING (machine_id)
JOIN sites s USING (site_id);

CREATE TABLE models (
    model_id integer GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
    name     text NOT NULL,
    sha256   text NOT NULL,
    labels   text[] NOT NULL,
    UNIQUE (name, sha256, labels)
);

-- One row per analysed window; `time` is the window's end. Replays and retries never
-- duplicate: the primary key is (point, window time) and inserts skip existing rows.
CREATE TABLE windows (
    point_id             integer NOT NULL REFERENCES points,
    time                 timestamptz NOT NULL,
    window_s             real NOT NULL,
    run_start            timestamptz NOT NULL,  -- the daemon run's clock origin
    seq                  bigint NOT NULL,       -- window counter of that run
    publish_time         timestamptz NOT NULL,
    state                text NOT NULL,         -- smoothed state (k-of-n votes, dwell)
    state_since          timestamptz NOT NULL,
    state_changed        boolean NOT NULL,
    confidence           real NOT NULL,
    window_state         text NOT NULL,         -- this window's own verdict
    unknown_reason       text,
    alarm_despite        text,
    model_id             integer NOT NULL REFERENCES models,
    p_healthy            real,
    p_outer_race         real,
    p_inner_race         real,
    p_ball               real,
    p_other              jsonb,                 -- labels outside the four above
    novelty              real NOT NULL,
    novelty_threshold    real NOT NULL,
    baseline_distance    real,
    beyond_baseline      boolean,
    rpm                  double precision,
    speed_source         text NOT NULL,
    velocity_rms_mm_s    real,                  -- 10-1000 Hz broadband
    iso_zone             text,                  -- ISO 20816-3 zone A..D (advisory)
    bpfo_1               real,                  -- envelope order-spectrum levels at the fault
    bpfo_2               real,                  -- orders' harmonics 1-3, channel unit
    bpfo_3               real,
    bpfi_1               real,
    bpfi_2               real,
    bpfi_3               real,
    two_bsf_1            real,
    two_bsf_2            real,
    two_bsf_3            real,
    band_floor           real,                  -- median bin RMS of the spectrum
    quality_ok           boolean NOT NULL,
    quality_flags        text[],                -- NULL when ok
    clipped_samples      integer NOT NULL,
    nan_samples          integer NOT NULL,
    dropout_samples      integer NOT NULL,
    missing_tacho_pulses integer NOT NULL,
    PRIMARY KEY (point_id, time)
) PARTITION BY RANGE (time);

-- 1-minute aggregates, kept long; sums so that means add up across batches.
CREATE TABLE minutes (
    point_id        integer NOT NULL REFERENCES points,
    minute          timestamptz NOT NULL,
    windows         integer NOT NULL,
    bad_quality     integer NOT NULL,
    unknown_windows integer NOT NULL,
    fault_windows   integer NOT NULL,          -- smoothed state neither healthy nor unknown
    last_time       timestamptz NOT NULL,
    last_state      text NOT NULL,
    rpm_sum         double precision NOT NULL,
    rpm_n           integer NOT NULL,
    velocity_sum    double precision NOT NULL,
    velocity_max    real,
    velocity_n      integer NOT NULL,
    bpfo_1_sum      double precision NOT NULL,
    bpfo_1_max      real,
    bpfi_1_sum      double precision NOT NULL,
    bpfi_1_max      real,
    two_bsf_1_sum   double precision NOT NULL,
    two_bsf_1_max   real,
    bands_n         integer NOT NULL,
    novelty_max     real,
    PRIMARY KEY (point_id, minute)
) PARTITION BY RANGE (minute);

CREATE VIEW minute_means AS
SELECT point_id, minute, windows, bad_quality, unknown_windows, fault_windows, last_state,
       rpm_sum / NULLIF(rpm_n, 0) AS rpm,
       velocity_sum / NULLIF(velocity_n, 0) AS velocity_rms_mm_s, velocity_max,
       bpfo_1_sum / NULLIF(bands_n, 0) AS bpfo_1, bpfo_1_max,
       bpfi_1_sum / NULLIF(bands_n, 0) AS bpfi_1, bpfi_1_max,
       two_bsf_1_sum / NULLIF(bands_n, 0) AS two_bsf_1, two_bsf_1_max,
       novelty_max
FROM minutes;

-- One event per change of the smoothed state; the full health JSON of that window.
CREATE TABLE events (
    event_id       bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
    point_id       integer NOT NULL REFERENCES points,
    time           timestamptz NOT NULL,
    from_state     text,                       -- NULL for a point's first known state
    to_state       text NOT NULL,
    previous_since timestamptz,                -- when from_state was entered
    held_s         double precision,           -- how long from_state held (its dwell)
    confidence     real NOT NULL,
    message        jsonb NOT NULL,
    acked_at       timestamptz,
    acked_by       text,
    ack_comment    text,
    UNIQUE (point_id, time)
);
CREATE INDEX events_time ON events (time);

CREATE TABLE point_latest (
    point_id          integer PRIMARY KEY REFERENCES points,
    time              timestamptz NOT NULL,
    run_start         timestamptz NOT NULL,
    seq               bigint NOT NULL,
    state             text NOT NULL,
    state_since       timestamptz NOT NULL,
    window_state      text NOT NULL,
    confidence        real NOT NULL,
    rpm               double precision,
    velocity_rms_mm_s real,
    iso_zone          text,
    quality_ok        boolean NOT NULL
);

-- The daemons' latest status message (source, pipeline, sinks counters).
CREATE TABLE point_status (
    point_id         integer PRIMARY KEY REFERENCES points,
    time             timestamptz NOT NULL,
    phase            text NOT NULL,
    state            text,
    windows          bigint NOT NULL,
    source_connected boolean NOT NULL,
    samples_lost     bigint NOT NULL,
    bad_frames       bigint NOT NULL,
    sink_dropped     bigint NOT NULL,
    message          jsonb NOT NULL
);

CREATE VIEW fleet_now AS
SELECT t.site, t.machine, t.asset, t.point, t.point_id, t.key,
       l.time, l.state, l.state_since, l.confidence, l.velocity_rms_mm_s, l.iso_zone, l.rpm,
       l.quality_ok, st.phase, st.time AS status_time, st.source_connected,
       (SELECT count(*) FROM events e WHERE e.point_id = t.point_id AND e.acked_at IS NULL)
           AS unacked_events
FROM asset_tree t
LEFT JOIN point_latest l USING (point_id)
LEFT JOIN point_status st USING (point_id);
