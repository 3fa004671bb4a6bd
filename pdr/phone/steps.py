"""Step detection from the acceleration norm (seed 004 Sec. 3.2), online and placement-independent.

Per seed 004 Sec. 3.2, on a uniform grid (the caller resamples; 20-25 Hz is enough, 50 Hz is used):

1. low-pass the accelerometer components (2nd-order Butterworth, ``cutoff_hz``), causal so that it
   runs batch by batch;
2. the norm ``a_n(t) = sqrt(a_x^2 + a_y^2 + a_z^2)`` of the filtered components (eq. 12);
3. a step starts ``t_s(k)`` at an upward crossing of the reference level ("g-crossing") that is followed,
   before the signal falls back below the reference and within ``max_rise_s``, by a peak whose height
   and rise rate exceed their limits, and at least ``min_interval_s`` after the previous step start;
4. the step ends ``t_e(k)`` when the next step starts, or ``max_step_s`` after its start.

Optionally (``beat_min_peak`` below ``min_peak``; off by default) a crossing that comes on the beat of the
last two accepted starts (its interval within ``beat_tolerance`` of theirs, itself at most ``max_step_s``)
needs only ``beat_min_peak``, and a rise rate scaled by the same ratio: a gentle hand-held walker's steps
(0.4-0.6 m/s^2 peaks) that keep the rhythm are steps. It is off: it costs the Oxford figure and over-counts
a swinging hand (see ``StepConfig``).

Gentle walkers (short test walks, sensor_logger_walks: 0.4-1.0 m/s^2 peaks, 0.9 s steps) need three rules, held
together by the walk's periodicity (the first two on by default, the third off, see it):

* Automatic gain (``floor_gain``): the peak floor follows the walk's own amplitude, ``floor_gain`` times the running
  RMS of ``a_n - reference`` over the last few seconds (``floor_tau_s``), clipped to ``[noise_peak, min_peak]``,
  where ``noise_peak`` lies above the peaks of a phone held still or standing in a pocket. A loud walk keeps
  ``min_peak``.
* Gait periodicity (``gait_min_corr``): the gain applies only while the signal repeats itself every stride, i.e. the
  normalised autocorrelation of ``a_n - reference`` (same window) at some lag of one stride (or one step) is at least
  ``gait_min_corr``; the kernel keeps running lagged products at every lag from two ``min_interval_s`` to two
  ``max_step_s``. Putting a phone away before a walk, handling it after one, or standing is not periodic: ungated,
  the gain counted them (the Oxford count error rose). Periodicity takes about a stride to show, so a crossing that
  passes the gain's floor before it does is kept as a *soft start*; when a bout confirms within two ``max_step_s`` after
  it, the gait-initiation rule (below) may take it as the walk's first step if it is as strong as the bout's steps
  (``short_bout_peak_ratio``). The first steps are emitted retroactively, like every bout's confirming steps.
  A candidate whose own stride (or step) is the period of the signal, with periodicity at least
  ``gait_confirm_corr``, confirms from ``gait_confirm_steps`` starts instead of ``min_bout_steps`` (a 4-step walk
  between two landmarks); the period must be the starts' own, since the window still holds the walk before a stop.
* Held-phone periodicity (``steady_tilt_deg``, ``steady_min_corr``): a phone held in front of the walker (texting,
  reading) is damped by the arm, and its norm carries the step as a small, multi-humped signal (0.3-1 m/s^2, two or
  three crossings per step, attitude_smartphones texting walks): the periodicity at a stride lag stays at 0.3-0.5,
  below ``gait_min_corr``, for most of the walk, so its steps stay soft and the walk breaks into bouts too short to
  confirm. The periodicity gate is there to keep handling out (putting a phone away, taking it out), and handling
  re-orients the phone, which walking does not: while the gravity direction in the device frame stays within
  ``steady_tilt_deg`` (RMS about its running mean over ``floor_tau_s``) of where it has been, ``steady_min_corr``
  periodicity is enough. Walking phones sway 1.5-4.5 deg RMS at that window (Oxford: pocket, hand, bag, armband;
  attitude_smartphones texting 1.7-4.2 deg, medians), swinging hands 3-10 deg. Tuned on Guillaume's two texting walks
  (attitude_smartphones; 0.3 is best there at 4-8 deg, 0.25 lets a pocket phone's handling through on
  inpocket-27-steps-Matan: 28 -> 67 steps), checked on Jakob's. Steps matched to the motion capture
  (``tools/walking_steps.py``): Guillaume Dist 31 -> 40 and NoDist 55 -> 82 of 131 and 134, Jakob Dist 49 -> 68 of
  151 (Jakob NoDist, 179 of 184, unchanged); Oxford, MobiFall and sensor_logger_walks counts unchanged walk by walk.
  The gate starts closed (a detector that has seen nothing does not take the phone for steady). The held-phone walks
  still lose steps: their starts are irregular (a missed step leaves a 1.6-2.2 s gap, a second hump a start 0.3 s
  after the first), and the bout rules need regular runs; dropping a start that comes within half a step of the last
  as a double crossing costs the back pockets' asymmetric steps and Oxford (1.06 -> 1.10 % or worse).
* Held walk (``held_walks``): with the gate above the held-phone walks' crossings are accepted (Guillaume's Dist
  texting walk: 113 starts, 96 of them on a motion-capture step), but the bout rules below drop most of them: a slow
  reader shuffling round a 5 x 5 m room steps every 0.7-1.2 s (motion capture), misses a crossing now and then (a
  1.6-2.2 s gap, beyond ``max_step_s``) and splits others, so few runs are regular enough to confirm. The bout rules
  are there to tell handling and standing from walking by the rhythm of the starts; a start decided while the phone
  holds its tilt (``steady_tilt_deg``) and the signal repeats at a stride (``steady_min_corr``) has that evidence
  from the held-phone gate already, so its bout rules are looser: confirmation from ``held_min_bout_steps`` starts
  with strides within ``held_bout_spread`` and steps within ``held_step_spread`` of the same leg's (the other rules
  unchanged, the gap ``max_step_s`` too: a 1.8 s gap for held walks bridged the IPIN walkers' stops at landmarks, IPIN
  p75 3.65 -> 3.81 m, and cost Oxford 0.37 -> 0.41 %). Tuned on Guillaume's texting walks
  (motion-capture steps matched within 0.3 s, ``tools/walking_steps.py``: Dist 40 -> 63 and NoDist 82 -> 97 of 131
  and 134), confirmed on Jakob's (Dist 68 -> 73 of 151, NoDist unchanged); Oxford, MobiFall, sensor_logger_walks and
  the non-walking recordings unchanged walk by walk, IPIN p75 3.65 -> 3.67 m (smoothed 2.97 -> 2.99), MS F3 3.54 m
  (these figures without the guards below, and the matched ones with the detector's times t0 = 0.36 s off the
  capture's axis, since corrected).
  Three guards, each a physical condition of a phone held in front by a walker who walks with it: the looser rules
  apply only (1) while gravity in the device frame is within ``handling_angle_deg`` of its direction at the latest
  start of a confirmed walk (the tilt the walker walks with: before any walk, and after the phone was turned, the
  ordinary rules judge), (2) while the phone's long axis lies more than ``held_min_axis_tilt_deg`` from the vertical
  (the placement detector's pocket rule: along a thigh it is near the vertical; the steady-tilt gate also opens in a
  back pocket, where the held rules took Guillaume NoDist BackPocket from 172 to 197 steps for 157 true), and (3) for
  starts at least ``short_bout_peak_ratio`` times that walk's median peak (the test a short run after a walk passes
  to walk on; weaker starts while standing at a landmark are not the walk going on: IPIN Trial27_repetition02 took 4
  steps at a 42 s stop without it). Without (1), handling at a fixed tilt before a walk (the synthetic handling of
  five detector tests) confirmed as a held walk. With the three, held walks on against off, steps (matched within
  0.3 s of a motion-capture step, ``pdr eval steps``): Guillaume Dist 52 -> 57 (35 -> 39) of 131 (his held walk before
  his first confirmed walk is lost to guard 1), NoDist 89 -> 106 (73 -> 76) of 134 (tuning), Jakob Dist 85 -> 91
  (74 -> 79) of 151, NoDist 186 (180) of 184 (check): the count nearer the truth, but few of the added starts within
  0.3 s of a true step; pockets, swinging and running unchanged walk by walk;
  Oxford, sensor_logger_walks and MobiFall unchanged; MS F3 p75 3.54 m (one trace +5 steps); IPIN p75 3.65 -> 3.61 m
  causal but 2.97 -> 2.99 m smoothed, from one step (Trial52_repetition01 +1: a missed step mid-walk, 83.8 -> 84.9 s,
  filled; that walk's causal p75 3.61 -> 2.67 m, smoothed 2.36 -> 2.51 m). On by default: that one step's 0.02 m of
  smoothed p75 against the counts of slow held walks nearer their truth; the motion-capture walking direction is
  unchanged by the added texting steps (361 -> 384 steps, causal mean 16.3 deg either way, ``pdr eval heading``).
  Before the first confirmed walk guard (1) has no tilt to compare with; a walker who reads while walking from the
  moment the recording starts then got no step until the ordinary rules confirmed a walk (Guillaume Dist: none in
  the first 65 s, about 65 true steps). There the held rules judge a candidate only if every one of its starts was a
  held one (``_held_run``: consecutive starts decided at a steady tilt, periodic, the long axis across the vertical),
  and it needs the ordinary ``min_bout_steps`` starts, not ``held_min_bout_steps``: handling before a walk is not
  periodic at a steady tilt, and the double crossings of a walk's first steps come before the held-phone gate opens
  (it starts closed). Guillaume Dist 57 -> 76 steps (39 -> 51 matched) of 131; the 333 other recordings of
  ``tools/walking_steps.py ../shared/data`` (Oxford, MobiFall walking and not walking, sensor_logger_walks, IPIN, MS,
  the other motion-capture walks) give the same steps.
* Held phone's peak floor (``held_peak_floor``): with the held walk the texting walks still matched 387 of 600
  motion-capture steps (``pdr eval steps ../shared/data/attitude_smartphones``: Guillaume Dist 51 of 131, NoDist 76 of
  134, Jakob Dist 80 of 151, NoDist 180 of 184). Why, per missed true step, from the kernel's decisions on the crossings
  within 0.3 s of it (Guillaume Dist / NoDist / Jakob Dist): every one has a crossing (no merged steps); its best
  crossing's peak lay under the floor for 39 / 44 / 24, was accepted by the kernel but dropped by the bout rules for
  30 / 9 / 29, and only soft (the gate shut) for 6 / 4 / 17. The floor those crossings missed is the automatic gain's,
  the running RMS of ``a_n - reference`` (0.29-0.48 m/s^2; ``min_peak`` for 15 / 5 % of them), their peaks 0.16-0.41
  and 0.11-0.35 m/s^2 (10-90 %, Guillaume), while the walks' matched steps peak at 0.73 (median). These are weak
  steps, not a cadence or a turn: the phone rises 13 / 11 / 9 mm over them against 20 / 17 / 16 mm over the matched
  ones, the walker moves at 0.30 / 0.24 / 0.20 m/s against 0.38 / 0.40 / 0.63 (shuffling round the 5 x 5 m room), the
  steps last 0.93 / 0.98 / 0.80 s (matched 0.89 / 0.83 / 0.65, all within ``max_step_s``) and turn at 17 / 26 / 12
  deg/s (matched 14 / 21 / 24; medians); the motion capture's own vertical acceleration of the phone shows the same
  small humps. A phone held in front moves with the arm and wrist as well as with the body's vault: the norm carries
  their motion (multi-humped, deep troughs) beside the steps, so its RMS sits about halfway up the steps' peaks and a
  step of half the walk's strength falls under it. The under-floor crossings' periodicity was 0.45 / 0.52 / 0.39
  (medians), half of them (49 / 43 / 50 %) in the held-phone gate's band (``steady_min_corr`` to
  ``gait_min_corr``), where the gain is open only because the phone is held steady, not because the signal is the
  steps'. There, while the phone is held in front (steady tilt, its long axis more than
  ``held_min_axis_tilt_deg`` from the vertical: the held walk's conditions, no handling and no thigh), the floor is
  instead, where lower, ``peak_ratio`` (the amplitude-relative floor's ratio) times the median peak of the last 8 clear
  steps (accepted above the RMS floor; at least 3), still at least ``noise_peak`` (seed 004 Sec. 3.2 step 3: the
  peak-height limit, set by the walk's own steps). Where the walk is clearly periodic the RMS is made of the steps and
  stays the floor. A first form without the band, with every accepted peak in the median and only for a crossing at
  least ``min_stride_ratio`` of the last step after the last start, matched 457 of 600 texting steps, but an IPIN
  walker's stop at a landmark (IPIN2023_T3_TrainingTrial05_repetition01, 104-108 s: small irregular humps after the
  walk, each lowering the median further) gained 7 steps (IPIN p75 3.54 -> 3.56 m, smoothed 2.96 -> 3.07 m) and three
  Oxford hand-held walks 1-2 (1.04 -> 1.05 %, filled truth 0.37 -> 0.41 %); on every carriage (not keyed to the held
  phone) back pockets and swinging hands gained their second humps (attitude_smartphones 768 -> 782 and 593 -> 619
  steps). On the seven IPIN and Oxford walks the first form changed, the band alone (with its rhythm condition) left one
  4 steps up, the clear-step median alone all seven changed, the two together (and the rhythm condition dropped,
  Guillaume's matched steps 152 -> 161) none. A held phone's floor at 0.7 of the RMS (no band) did about as well on
  texting (452), not checked further: the steps' own strength is the reference the floor is about.
  Tuned on Guillaume, checked on Jakob (``pdr eval steps``, matched within 0.3 s; steps for true): Guillaume Dist
  51 -> 78 (76 -> 109 for 131), NoDist 76 -> 83 (106 -> 114 for 134); Jakob Dist 80 -> 87 (94 -> 105 for 151), NoDist
  180 (186 for 184) unchanged; texting 387 -> 428 of 600 (64.5 -> 71.3 %), mean count error 25.4 -> 15.8 %. The other
  carriages' walks, and ``pdr eval steps`` on oxford_step_counter, sensor_logger_walks and mobifall_v2_pocket,
  ``pdr eval ipin`` and ``pdr eval ms``: unchanged line for line. Left: the crossings still under the floor peak at
  0.24 m/s^2 (median, Guillaume), under ``noise_peak``; the rest are accepted starts the bout rules drop (17 / 8 / 26)
  or soft starts (6 / 4 / 17: Jakob Dist walks 10-60 s with a periodicity of 0.2-0.4 and no step).
* Slow walker's missed steps (``slow_missed_steps``): at 0.9 s steps one missed step leaves a gap longer than
  ``max_step_s``, which must not end the walk; a confirmed bout whose shortest missed-step gap
  (``min_missed_ratio`` strides) exceeds ``max_step_s`` infers the step in a gap of up to ``max_missed_ratio``
  strides. At a faster pace such a gap is a stop (IPIN hand-held walkers stop at landmarks). Off by default: on the
  IPIN repetition-02 walks (the held-out half) it raised the hand-held leg-direction error with drift elimination
  (the drift elimination's benefit almost vanished) and the p75 (``pdr eval ipin``). The
  short walks after a walk (below) keep the steps after such a gap without inferring the missed one.

The reference level is not the constant g but a slow causal low-pass of ``a_n`` (``reference_hz``), which
absorbs accelerometer scale and bias errors. The peak-height limit adapts to the carriage: it is the
larger of ``min_peak`` and ``peak_ratio`` times a running mean of accepted peak heights (a phone in a
trouser pocket sees 5-10 m/s^2 peaks, a hand-held phone 1-2 m/s^2).

Phone handling and standing are rejected by requiring walking bouts: a step is reported only when it
belongs to a run of starts that walks with a steady rhythm. The rhythm is judged per *stride* (two
steps, ``s(k) - s(k-2)``), not per step: with the phone on one side of the body (trouser pocket, bag,
armband) the two legs give crossings at alternating short and long intervals (e.g. 0.35 s / 0.65 s in a
back pocket) while the stride stays regular.

* A bout is *confirmed* when ``min_bout_steps`` consecutive starts, each within ``max_step_s`` of the
  previous one, have strides within a factor ``bout_spread`` of each other (longest / shortest). Putting
  a phone into a pocket or bag, or taking it out, gives peaks at irregular intervals and is dropped. The
  legs alternate, so each step must also agree with the same leg's step one stride later (ratio within
  ``[1/step_spread, step_spread]``): a stride can look regular while a double crossing splits it into
  0.3 s + 0.7 s on a walk of symmetric 0.5 s steps. The confirming starts must also come at a walking pace:
  their median step at least ``min_bout_step_s`` (0.38 s, about 2.6 steps/s, faster than people walk).
  Putting a phone into a pocket gives regular peaks 0.3-0.4 s apart; without this limit such a run
  confirmed a bout at half the walk's stride and the missed-step rule below then put a step between every
  two real ones (60 steps on a real 27-step pocket walk). Once confirmed, the bout also takes the earlier starts
  (gait initiation) whose strides stay within ``[min_stride_ratio, max_stride_ratio]`` times the bout's
  median stride and whose steps pass the same-leg test.
* A candidate bout (not yet confirmed) breaks at a start off the rhythm of its recent strides. It then
  keeps its latest starts whose strides agree with the new start's within ``bout_spread`` (a walk that
  begins right after the phone is put away: the long, irregular handling strides inflate the median and
  make the walk's first strides look off-rhythm; before, those first steps were dropped with the
  handling). Such a re-anchored candidate cannot become a short walk (below): it did not start after a stop.
* A double crossing in a candidate bout (``double_crossings``): the feet land once per step, so a start whose
  intervals to both neighbours are shorter than any walking step (``min_bout_step_s``) and which together make one
  step of the candidate's rhythm (less than 0.75 of its median stride, nearer a step than a stride) is the same
  contact's second hump, and is dropped when the start after it arrives, if the step it leaves agrees with the same
  leg's step one stride before within ``short_bout_spread`` (handling before a walk splits no regular step). Kept, it
  broke the candidate's rhythm at gait initiation: Nexus_Jamie_Hard_InHand_2 lost its first three steps (301 -> 304
  of 306 contact-switch steps; no other Oxford, MobiFall, IPIN, MS, Sensor Logger or attitude_smartphones recording
  changes). A back pocket's asymmetric steps (0.35 s / 0.65 s) have one long side and span a stride. Confirmed bouts
  are left alone: on the Oxford walks the rule changed no confirmed bout's step.
* A confirmed bout goes on while starts come within ``max_step_s``. It ends early at a start that is both
  off the rhythm (stride outside ``[min_stride_ratio, max_stride_ratio]`` times the median of the recent
  strides) and weak (peak below ``weak_peak_ratio`` times the median of the recent step peaks): the walk
  has stopped and the phone is being handled. Either sign alone (a turn, a missed or a soft step) does
  not end a bout. The starts after the end form a new candidate bout.
* Short walks between stops (a hand-held walker passing landmarks: four steps, a stop, four steps, then
  the walk goes on) never reach ``min_bout_steps``. A candidate run of at least ``min_short_bout_steps``
  starts whose strides agree within ``short_bout_spread`` is kept when it breaks off; when a bout confirms
  after it, the run is steps too if it ends between half a stride and ``short_bout_gap_s`` before the
  bout (or before the next kept run), walks at the bout's rhythm (median stride within
  ``[min_stride_ratio, max_stride_ratio]`` of the bout's) and is as strong (median peak at least
  ``short_bout_peak_ratio`` of the bout's). Putting a phone away before a walk fails the last test (softer
  peaks) or the stride test. On the IPIN 2023 hand-held logs this recovers the 8 steps of IPIN trial 21
  repetition 1 between its first three landmarks; the Oxford counts are unchanged. Three starts (two steps, one
  stride: its regularity test is empty) are enough here, since the bout after the run vouches for it by the rhythm
  and strength tests: the MS surveyors walk two or three steps between waypoints 1.4-3 m apart at the start of a
  trace, stopping at each (the acceleration norm stays within 0.1-1 m/s^2 of its reference for 1-5 s there, against
  3-12 m/s^2 peaks walking), and four starts lost those steps (up to 6 m before the first counted step). With three
  (four before): MS site2 F3 p75 3.54 -> 3.52 m (tuning; 3 traces better, 5dd51a76 worse, 3.13 -> 4.52 m: its 7
  steps between waypoints 1.4 m apart are counted, but taken at the model's step length), F4 5.44 m unchanged (check;
  5dd3bbd6 1.53 -> 1.06 m, no trace worse), IPIN p75 3.61 -> 3.60 m causal, 2.99 -> 2.95 m smoothed (repetition01
  trials 05 and 25 and repetition02 trials 05 and 22 better, repetition02 trial 04 worse by 0.2 m absolute, better
  aligned), attitude_smartphones 12.14 -> 12.11 % (motion-capture matched 2862 -> 2869); Oxford, sensor_logger_walks
  and MobiFall unchanged walk by walk.
* Short walks after a walk (the mirror of the rule above): a confirmed bout ends at a gap longer than
  ``max_step_s``, which a gentle walker's one soft missed step makes (0.9 s steps leave 1.6-1.8 s), or at a brief
  stop; the steps after it are too few to confirm a bout of their own when the walk ends soon after (a short test
  walk's last steps). When such a regular run (as above) breaks off or the recording ends, it is steps if it walks
  on from the last confirmed bout by the same three tests: it starts between half a stride and
  ``short_bout_gap_s`` after that bout's last start, at its rhythm and with its strength. Starts between them
  that form no such run, or a bout that ended in handling (the phone turned among its held steps, walk-end rule
  below), end the walk for good. Unlike the slow walker's rule the missed step itself is not inferred, and a
  confirmed bout still ends at the gap. The run is reported when it closes (at most ``max_step_s`` after its last
  start), like every bout's confirming steps.
* A walk alone (``lone_walks``): a recording of a few steps only (a 6.7 s MS trace: two steps out to a waypoint 1 m
  away and back) has a regular run with no bout after it to claim it, nor one within ``short_bout_gap_s`` before it.
  Such a run is steps if it has at least ``min_lone_walk_steps`` starts (no walk vouches for it: three-start runs of
  getting into or out of a car passed the tests below, MobiFall CSI + CSO 13 -> 31 steps), and, besides the
  short-walk regularity, it walks at a walking pace (median step
  ``min_bout_step_s`` to ``max_step_s``) with the same-leg agreement (``step_spread``), and the phone keeps its tilt:
  the gravity direction in the device frame stays within ``handling_angle_deg`` of its direction at the run's first
  start. Getting into or out of a car or sitting down turns a pocket phone with the thigh (69-107 deg on the ten
  MobiFall car recordings with such a run, which an earlier rule without this test counted); the walking ones turned
  2-12 deg. The run is reported when the recording ends: until then a bout may still confirm after it and claim it
  (or, failing the short-walk tests, drop it).
* A step too soft to pass the peak rules (a hand-held phone damps some steps to a flat hump) leaves a
  gap of about one stride between two starts of a confirmed bout. When the gap is within
  ``[min_missed_ratio, max_missed_ratio]`` times the median stride and the start after it is not weak,
  the missed step is inferred: its start follows the previous one as that followed its predecessor
  (the legs alternate), its peak is the mean of its neighbours'. Not in a gap shorter than two walking steps
  (``2 min_bout_step_s``): two steps there would be faster than people walk, so the bout's rhythm is not a walk's.
  A bout confirmed at such a rhythm (putting a phone into a pocket gives regular peaks 0.3-0.4 s apart; a median
  step of exactly ``min_bout_step_s`` passes the confirmation) otherwise put a step between every two real ones of
  the walk after it, and the rhythm it kept was its own: the Sensor Logger pocket walk
  (inpocket-27-steps-Matan, 28 steps) with its first 5 s cut off gave 62 steps and 46 m, now 35 steps and 20 m
  (the 7 extra are the handling bout's own starts; a tilt test at confirmation that drops them, as the lone-walk
  rule's, cost the hand-held IPIN walks up to a third of their steps). ``tools/walking_steps.py ../shared/data``:
  Oxford, MobiFall, sensor_logger_walks, IPIN and the motion-capture walks unchanged but the running ones (Guillaume
  329 -> 327 steps for 321 true, 321 -> 319 matched; Jakob 325 -> 310 for 276, 267 -> 266 matched); two short MS
  F3 traces lose one step each (p75 4.32 -> 3.35 m and 5.08 -> 4.03 m; ``pdr eval ms``: F3 3.52 -> 3.43 m, F4
  unchanged).
* Walk end (step 4 of seed 004 Sec. 3.2 ends a step at the next start; this decides whether there is a
  step at all). When a walk stops, the phone is often taken out of the pocket or bag, or the bag swings
  on: peaks keep coming at a walking-like pace, so the rhythm rules above count them. Two signs tell
  them apart, judged per step over the stride around it (from the decision of the previous start to
  that of the next one, so known when the step is reported):

  - *weak*: the RMS of ``a_n - reference`` over the stride is below ``weak_energy_ratio`` times the
    median of the bout's recent steady strides (the walker has stopped pushing off);
  - *turned*: the gravity direction in the device frame (components low-passed at ``gravity_hz``)
    turns by more than ``handling_angle_deg`` over the stride (the phone is being re-oriented).

  A weak step, and a turned step that follows one, is held back; the next steady step reports the held
  ones (a soft step or a turn inside a walk changes nothing but latency). Held steps that keep coming and, as a
  run of ``soft_walk_steps``, are not weak (their median RMS passes the weak test) are the walk going on, turned
  or not, and are reported: handling after a walk is weak, the walker has stopped pushing off. Some hand-held
  walkers turn the phone by 40-170 deg every stride (IPIN trial 05 repetition 02), so after one weak stride every
  step was "turned" and held, and the bout's end dropped them all: with that log's first 2 s cut off, 22 steps of
  13-29 s were lost (147 steps against 179 uncut; now 163). ``tools/walking_steps.py ../shared/data`` gives the same
  steps on all its recordings. If the bout ends while steps
  are held and the phone turned among them, the walk ended in handling: the first held step is kept
  (the walk's last step is soft, the feet come together), the rest and the bout's last start are
  dropped. Without a turn, held steps are a slow end of the walk and are reported. A run of
  ``soft_walk_steps`` held steps without a turn is a walk in a softer carriage (the phone moved from a
  pocket to the hand while walking): it is reported and becomes the bout's strength reference, so a
  long walk is never held back.

``pdr eval steps`` prints the figures of the defaults per walk, with a plain peak detector's count beside each. The
rules above were kept because they lowered the mean absolute count error on the Oxford step-counter walks (pocket,
hand, bag and armband; re-anchoring, the walk-end rule and the same-leg rule each; ``step_spread`` chosen on the odd
half of the 42 walks, sorted by name, and checked on the even half), and with it the count of contact-switch edges with
no detected start within 0.35 s plus detected starts with no edge: the count error hides compensating errors. The
contact-switch truth itself holds switch bounces (a second rising edge of the same foot 0.1-0.3 s after the first,
13-20 per walk on some armband and swinging-arm walks) and, on some walks, drop-outs (one foot's edges missing for one
or two strides, e.g. Samsung_Dario_Hard_FrontPocket_1) and edges while standing after the walk: a counter that found
exactly the bounce-free steps would still score 0.88 % against it. The walk-end rule is not sensitive to
``handling_angle_deg`` (20-30 deg give the same counts) nor to ``soft_walk_steps`` (8 and more); ``weak_energy_ratio``
0.4 or 0.6 count worse. With the bounces removed and one switch's drop-outs filled from the other foot (the feet
alternate: :func:`pdr.evaluation.scoring.alternating_step_count`), the defaults score 0.37 % on those 42 walks (Jamie's
22 walks 0.43 %, Carmelo's and Dario's 20 walks 0.30 %). Against the shipped truth (raw edges, 1.04 %) a counter that
found exactly the corrected truth's steps would score 0.88 %: the 0.5 % asked of it there is below the truth's own
error. What is left against the corrected truth, matched contact by contact (0.35 s): the first contact of a walk from
standing (no crossing of its own, or merged with the push-off's: fewer steps than contacts in the first 3 s on 16 of
the 42 walks, while on 12 a push-off crossing about a step before the first contact is counted, more steps than
contacts) and the last, closing step (the trailing foot placed beside the other: a hump of at most 0.7 m/s^2 and 40 %
of the walk's peaks, often none above the noise; fewer steps than contacts in the last 3 s on 20 of the 42 walks). A
closing-step rule (one more step when a crossing above ``noise_peak`` comes within ``max_step_s`` after a walk's last
start) was tried and dropped: 0.43 -> 0.40 % on Jamie's walks but 0.30 -> 0.33 % on the others; the same hump follows
the last start on walks whose closing step was counted already.

Every decision depends only on the samples, never on how they were split into batches, so feeding a
recording in chunks gives the same steps as one batch (:class:`StepDetector` keeps the state).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pdr.errors import InputError
from pdr.filters import iir
from pdr.filters.compiled import kernel
from pdr.phone.placement_detect import PlacementDetectConfig

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class StepConfig:
    """Parameters of the step detector (defaults fitted on the Oxford step-counter development walks).

    Attributes
    ----------
    cutoff_hz
        Low-pass cut-off of the accelerometer components (Hz).
    reference_hz
        Cut-off of the slow low-pass that gives the crossing reference level (Hz).
    min_peak
        Absolute minimum peak height above the reference (m/s^2).
    peak_ratio
        Minimum peak height as a fraction of the running mean of accepted peak heights.
    min_rise_rate
        Minimum rise rate from the crossing to the peak (m/s^3).
    max_rise_s
        Longest time from the crossing to the peak (s).
    min_interval_s
        Shortest time between two step starts (s).
    max_step_s
        Longest step; also the longest pause inside a walking bout (s).
    min_bout_steps
        Fewest consecutive steps that make a walking bout.
    amplitude_tau_s
        Time constant (s) with which the running peak amplitude decays between accepted steps, so a
        burst of handling does not raise the threshold for good.
    bout_spread
        Largest ratio of the longest to the shortest stride among the ``min_bout_steps`` starts that
        confirm a walking bout.
    min_stride_ratio, max_stride_ratio
        Band of a regular stride, as a fraction of the median of the recent strides of the bout.
    weak_peak_ratio
        A start whose peak is below this fraction of the median of the bout's recent peaks is weak.
    min_missed_ratio, max_missed_ratio
        In a confirmed bout, a gap between two starts within this band times the median recent stride
        holds one missed step, which is inferred.
    gravity_hz
        Cut-off of the low-pass of the accelerometer components that gives the gravity direction in the
        device frame (Hz).
    handling_angle_deg
        A step over whose stride the gravity direction turns by more than this (deg) is phone handling.
    weak_energy_ratio
        A step whose stride RMS of ``a_n - reference`` is below this fraction of the bout's steady steps'
        median is weak.
    soft_walk_steps
        Weak steps in a row, none with the phone turning, that make a walk in a softer carriage (reported,
        and their strength becomes the bout's reference).
    min_short_bout_steps, short_bout_gap_s
        A run of at least this many regular starts too short to confirm a bout, ending at most this long
        (s) before the next run of starts, is a short walk when that next run confirms with the same rhythm; so is
        one starting at most this long after the last start of a confirmed bout, with its rhythm and strength.
    short_bout_spread
        Largest ratio of the longest to the shortest stride of a short walk (tighter than ``bout_spread``:
        two or three strides are weaker evidence of walking than a confirmed bout's).
    short_bout_peak_ratio
        A short walk is as strong as the walk next to it: its median peak is at least this fraction of the
        median peak of the bout that confirms after it or that it follows (putting a phone away, or handling it
        after a walk, gives softer peaks).
    step_spread
        Largest ratio between a step (start to next start) and the same leg's step one stride later, in the
        starts that confirm a bout and in the gait-initiation starts it takes before them.
    beat_min_peak, beat_tolerance
        Peak-height floor (m/s^2) of a crossing on the beat of the last two accepted starts (its interval
        within this fraction of theirs), instead of ``min_peak``. Equal to ``min_peak`` (the default) turns the
        rule off: with 0.3 and 0.35 it counts gentle hand-held walks, but raises the Oxford error and
        over-counts a swinging hand (half-stride arm peaks on the beat); figures in the commit that added it.
    min_bout_step_s
        Shortest median step (s) of the starts that confirm a walking bout (faster is handling, not walking).
    slow_missed_steps
        A confirmed bout whose stride times ``min_missed_ratio`` is longer than ``max_step_s`` infers a missed step in
        a gap of up to ``max_missed_ratio`` strides instead of ending (a slow walker: 0.9 s steps leave a 1.6-1.8 s
        gap). It goes with the automatic gain below.
    floor_gain, floor_tau_s, noise_peak
        Automatic gain of the peak floor: the floor is ``floor_gain`` times the running RMS (m/s^2) of
        ``a_n - reference`` (exponential window, time constant ``floor_tau_s``), clipped to
        ``[noise_peak, min_peak]``, and the rise-rate limit scales with it. ``noise_peak`` (m/s^2) lies above the
        peaks of a phone held still or standing in a pocket (99th percentile of the peaks over the 45 min of
        MobiFall standing: 0.19 m/s^2). ``floor_gain`` 0 turns it off (``min_peak`` alone). Ungated (``gait_min_corr``
        0) it raises Oxford's error (1.06 -> 1.14 %, handling before and after walks).
    gait_min_corr
        Gait periodicity gate of the automatic gain: the gain lowers the floor only while the normalised
        autocorrelation of ``a_n - reference`` (exponential window ``floor_tau_s``) at some lag of one stride (two
        steps of ``min_interval_s`` to two of ``max_step_s``) is at least this; 0 turns the gate (and soft starts)
        off. 0.5 keeps the gain's Oxford cost away and still counts the gentle Sensor Logger walks; 0.4 lets one Oxford
        walk's handling through (Samsung_Carmelo_Hard_FrontPocket_1, +3), 0.6 loses the 20-step walk.
    gait_confirm_corr, gait_confirm_steps
        A candidate bout confirms from ``gait_confirm_steps`` starts (instead of ``min_bout_steps``) when the
        periodicity is at least ``gait_confirm_corr`` at the lag of their own stride or step (within
        ``short_bout_spread``); ``gait_confirm_corr`` 0 turns it off. It keeps the two 4-step runs of IPIN trial 21
        between landmarks, which the gain's extra soft turning steps otherwise break off.
    lone_walks
        Count a regular short run that no walk comes before or after (a recording of a few steps only) when it walks
        at a walking pace and the phone keeps its tilt over it (module docstring); reported when the recording ends.
    min_lone_walk_steps
        Fewest starts of such a walk alone (more than ``min_short_bout_steps``: no walk next to it vouches for it).
    steady_tilt_deg, steady_min_corr
        Held-phone periodicity gate: while the phone is held steady, i.e. the RMS angle (deg) of the gravity direction
        in the device frame about its running mean (exponential window ``floor_tau_s``) is at most
        ``steady_tilt_deg``, the automatic gain needs a periodicity of only ``steady_min_corr`` instead of
        ``gait_min_corr`` (module docstring). ``steady_tilt_deg`` 0 turns it off.
    held_walks, held_min_bout_steps, held_bout_spread, held_step_spread
        Held walk: a start decided while the held-phone gate is open (steady tilt and periodicity at least
        ``steady_min_corr``) is judged by the bout rules with ``min_bout_steps``, ``bout_spread`` and ``step_spread``
        replaced by these (module docstring). ``held_walks`` False turns it off.
    held_min_axis_tilt_deg
        Held walk only while the phone's long axis is more than this (deg) from the vertical: a phone along the thigh
        (a pocket) has it near the vertical, one held to be read lies across it
        (:class:`pdr.phone.placement_detect.PlacementDetectConfig` ``pocket_max_axis_tilt_deg``).
    held_peak_floor
        Held phone's peak floor: while the phone is held in front (steady tilt as ``steady_tilt_deg``, long axis more
        than ``held_min_axis_tilt_deg`` from the vertical) and the periodicity is in the held-phone gate's band
        (``steady_min_corr`` to ``gait_min_corr``), a crossing needs, in place of the automatic gain's RMS floor where
        lower, only ``peak_ratio`` times the median peak of the last clear steps (module docstring). False turns it
        off.
    double_crossings
        Drop a candidate bout's start that splits one step of its rhythm in two (module docstring); False keeps it.
    """

    cutoff_hz: float = 3.0
    reference_hz: float = 0.2
    min_peak: float = 0.6
    peak_ratio: float = 0.35
    min_rise_rate: float = 2.0
    max_rise_s: float = 0.4
    min_interval_s: float = 0.3
    max_step_s: float = 1.2
    min_bout_steps: int = 6
    amplitude_tau_s: float = 3.0
    bout_spread: float = 1.35
    min_stride_ratio: float = 0.7
    max_stride_ratio: float = 1.4
    weak_peak_ratio: float = 0.25
    min_missed_ratio: float = 0.85
    max_missed_ratio: float = 1.2
    gravity_hz: float = 0.3
    handling_angle_deg: float = 25.0
    weak_energy_ratio: float = 0.5
    soft_walk_steps: int = 10
    min_short_bout_steps: int = 3
    short_bout_gap_s: float = 3.0
    short_bout_spread: float = 1.15
    short_bout_peak_ratio: float = 0.6
    step_spread: float = 1.67
    beat_min_peak: float = 0.6
    beat_tolerance: float = 0.2
    min_bout_step_s: float = 0.38
    floor_gain: float = 1.0
    slow_missed_steps: bool = False
    floor_tau_s: float = 3.0
    noise_peak: float = 0.25
    gait_min_corr: float = 0.5
    gait_confirm_corr: float = 0.7
    gait_confirm_steps: int = 4
    lone_walks: bool = True
    min_lone_walk_steps: int = 4
    steady_tilt_deg: float = 5.0
    steady_min_corr: float = 0.3
    double_crossings: bool = True
    held_walks: bool = True
    held_min_bout_steps: int = 4
    held_bout_spread: float = 2.0
    held_step_spread: float = 3.0
    held_min_axis_tilt_deg: float = PlacementDetectConfig.pocket_max_axis_tilt_deg
    held_peak_floor: bool = True

    def __post_init__(self) -> None:
        for name in ("cutoff_hz", "reference_hz", "max_rise_s", "min_interval_s", "max_step_s",
                     "min_stride_ratio", "gravity_hz", "handling_angle_deg", "min_peak", "beat_min_peak",
                     "floor_tau_s", "noise_peak"):
            if not getattr(self, name) > 0:
                raise InputError(f"{name} must be positive", field=name, source="step config")
        if self.steady_tilt_deg < 0:
            raise InputError("steady_tilt_deg must not be negative", field="steady_tilt_deg", source="step config")
        if self.floor_gain < 0:
            raise InputError("floor_gain must not be negative", field="floor_gain", source="step config")
        if self.soft_walk_steps < 1:
            raise InputError("soft_walk_steps must be at least 1", field="soft_walk_steps", source="step config")
        if self.min_short_bout_steps < 3:
            raise InputError("min_short_bout_steps must be at least 3", field="min_short_bout_steps",
                             source="step config")
        if self.min_bout_steps < 1:
            raise InputError("min_bout_steps must be at least 1", field="min_bout_steps", source="step config")
        if self.held_min_bout_steps < 1:
            raise InputError("held_min_bout_steps must be at least 1", field="held_min_bout_steps",
                             source="step config")
        if not (self.held_bout_spread >= 1.0 and self.held_step_spread >= 1.0):
            raise InputError("held_bout_spread and held_step_spread must be at least 1", field="held_bout_spread",
                             source="step config")
        if not self.max_missed_ratio > self.min_missed_ratio > 0:
            raise InputError("need 0 < min_missed_ratio < max_missed_ratio", field="min_missed_ratio",
                             source="step config")
        if not self.max_stride_ratio > self.min_stride_ratio:
            raise InputError("max_stride_ratio must exceed min_stride_ratio", field="max_stride_ratio",
                             source="step config")
        if not (self.bout_spread >= 1.0 and self.short_bout_spread >= 1.0 and self.step_spread >= 1.0):
            raise InputError("bout_spread must be at least 1", field="bout_spread", source="step config")


@dataclass(frozen=True)
class Steps:
    """Detected steps on a uniform grid.

    Attributes
    ----------
    start_idx, end_idx
        (K,) grid indices of step start ``t_s(k)`` and end ``t_e(k)`` (end exclusive), counted from the
        first sample the detector ever saw.
    confirm_idx
        (K,) grid index at which the step became known (online latency): the sample after which it was
        reported.
    peak
        (K,) peak height above the reference (m/s^2).
    """

    start_idx: IntArray
    end_idx: IntArray
    confirm_idx: IntArray
    peak: FloatArray

    def __len__(self) -> int:
        return int(self.start_idx.size)

    @staticmethod
    def empty() -> Steps:
        z = np.zeros(0, dtype=np.int64)
        return Steps(z, z.copy(), z.copy(), np.zeros(0))


# Kernel state layout.
_S_REF_INIT, _S_PREV_D, _S_CAND, _S_CAND_START, _S_CAND_PEAK, _S_CAND_PEAK_I, _S_AMP, _S_LAST, _S_INDEX, \
    _S_LAST2, _S_MS = range(11)
_S_SIZE = 11
#: After the fixed slots: the ring position, a ring of the last ``max_lag + 1`` values of ``a_n - reference`` and the
#: running lagged products at lags ``min_lag..max_lag`` (gait periodicity, :func:`_gait_lags`).
_S_RING = _S_SIZE
#: Starts kept of a confirmed bout (stride and peak medians, last step duration) and of a candidate bout.
_BOUT_HISTORY = 10
_CANDIDATE_HISTORY = 12
#: Recent starts whose strides give the bout's rhythm, and recent peaks that give its strength.
_STRIDE_HISTORY = 8
_PEAK_HISTORY = 10
#: Soft starts kept (passed the automatic gain's floor before the walk was periodic), waiting for a bout.
_SOFT_HISTORY = 4
#: An interval shorter than this many strides is one step, not a stride (midway between half a stride and one).
_STEP_OF_STRIDE = 0.75
#: Short regular runs kept, waiting for a bout to confirm after them.
_SHORT_HISTORY = 4
#: Peaks of the last clear steps (accepted above the automatic gain's RMS floor) whose median is the held phone's recent
#: step strength (held_peak_floor): kept in the kernel's state after the periodicity's lagged products, their count
#: before them.
_PEAK_RING = 8
#: Fewest accepted peaks before the held phone's peak floor applies.
_PEAK_RING_MIN = 3
#: A start of a walking bout: (start index, peak, decided at, running energy and unit gravity (x, y, z) there).
_Start = tuple[int, float, int, float, float, float, float]
#: A doubtful step held back: (start index, end index, peak, phone turned, stride RMS).
_Held = tuple[int, int, float, bool, float]


def _gait_lags(c: StepConfig, fs: float) -> tuple[int, int]:
    """Lag range (samples) searched for the stride period: two shortest steps to two longest steps."""
    return max(1, int(round(2 * c.min_interval_s * fs))), int(round(2 * c.max_step_s * fs))


def _kernel_size(c: StepConfig, fs: float) -> int:
    lo, hi = _gait_lags(c, fs)
    return _S_RING + 1 + (hi + 1) + (hi - lo + 1) + 1 + _PEAK_RING


def _median(values: Sequence[float]) -> float:
    """Median of a short list of finite numbers, as ``np.median`` (the mean of the middle two for an even count)
    without its per-call overhead: the rhythm rules take several per candidate step (40 us each with numpy).
    """
    return float(statistics.median(values))


@kernel
def _ring_median(ring: FloatArray, n: int) -> float:
    """Median of ``ring[:n]`` (``n`` >= 1 finite numbers, a few), as ``np.median``: sorted by insertion in a copy, the
    middle one or the mean of the middle two. In the step kernel instead of ``np.median``, whose numba implementation
    lives in ``numba.np.arraymath``: loading a kernel that calls it imports that module, 0.25-0.4 s of a process's
    start (``tests/pdr/filters/test_compiled.py``).
    """
    v = ring[:n].copy()
    for i in range(1, n):
        x = v[i]
        j = i - 1
        while j >= 0 and v[j] > x:
            v[j + 1] = v[j]
            j -= 1
        v[j + 1] = x
    h = n // 2
    return v[h] if n % 2 == 1 else (v[h - 1] + v[h]) / 2.0


def _strides(starts: Sequence[int]) -> list[int]:
    """Stride lengths (samples) of consecutive step starts: ``starts[i + 2] - starts[i]`` (the same leg)."""
    return [starts[i + 2] - starts[i] for i in range(len(starts) - 2)]


def _initial_ms(c: StepConfig) -> float:
    """Starting mean square of ``a_n - reference`` ((m/s^2)^2): the automatic gain starts at ``min_peak`` and
    learns the walk's amplitude over ``floor_tau_s`` (a detector that has heard nothing yet does not trust
    small peaks: putting the phone away before a walk gives them).
    """
    return (c.min_peak / c.floor_gain) ** 2 if c.floor_gain > 0 and not c.gait_min_corr > 0 else 0.0


@kernel
def _detect_kernel(d: FloatArray, st: FloatArray, fs: float, min_peak: float, peak_ratio: float,
                   min_rate: float, max_rise: int, min_interval: int,
                   amp_tau: float, beat_peak: float, beat_tol: float,
                   max_step: int, floor_gain: float, floor_tau: float,
                   noise_peak: float, track_corr: bool, min_corr: float, min_lag: int,
                   max_lag: int, steady: NDArray[np.bool_], steady_corr: float,
                   held: NDArray[np.bool_], held_ratio: float
                   ) -> tuple[IntArray, FloatArray, IntArray, FloatArray, NDArray[np.bool_], IntArray]:
    """Crossing/peak state machine over ``d = a_n - reference``; returns accepted and soft starts as (start, peak,
    decided_at, periodicity there, soft, lag of the periodicity's peak in samples).

    A crossing on the beat (its interval from the last accepted start within ``beat_tol`` of the interval
    before, itself at most ``max_step``) needs a peak of ``beat_peak`` instead of ``min_peak``, and a rise rate
    scaled by the same ratio (the same step shape, softer); the amplitude-relative limit is unchanged.

    Automatic gain: the floor (``min_peak``, or ``beat_peak`` on the beat) is lowered to ``floor_gain`` times the
    running RMS of ``d`` (exponential window ``floor_tau`` s, state ``_S_MS``), but not below ``noise_peak``; the
    rise-rate limit scales with the floor.

    Gait periodicity (``min_corr`` above 0): the gain applies only while the walk is periodic, i.e. the normalised
    autocorrelation of ``d`` (the same exponential window) at some lag of one stride (``min_lag..max_lag``) is at
    least ``min_corr``. Walking repeats itself every stride; putting a phone away or standing does not. Where
    ``steady[i]`` (the phone held at a steady tilt: no handling), ``steady_corr`` is enough.

    Held phone's peak floor (``held_ratio`` above 0): where ``held[i]`` (held in front) and the periodicity is in
    ``[steady_corr, min_corr)``, the gain's floor is at most ``held_ratio`` times the median peak of the last
    ``_PEAK_RING`` accepted starts that passed the RMS floor (at least ``_PEAK_RING_MIN`` of them).
    """
    n = d.size
    ring_n = max_lag + 1
    ring0 = _S_RING + 1
    sums0 = ring0 + ring_n
    pk0 = sums0 + (max_lag - min_lag + 1)
    gated = min_corr > 0.0
    corrs = np.empty(n)
    softs = np.zeros(n, dtype=np.bool_)
    lags = np.zeros(n, dtype=np.int64)
    starts = np.empty(n, dtype=np.int64)
    peaks = np.empty(n)
    decided = np.empty(n, dtype=np.int64)
    m = 0
    base = int(st[_S_INDEX])
    decay = 1.0 - 1.0 / (amp_tau * fs)
    ms_alpha = 1.0 / (floor_tau * fs)
    for i in range(n):
        gi = base + i
        x = d[i]
        st[_S_AMP] *= decay
        st[_S_MS] += ms_alpha * (x * x - st[_S_MS])
        corr = 0.0
        best_lag = 0
        if track_corr:
            pos = int(st[_S_RING])
            st[ring0 + pos] = x
            for lag in range(min_lag, max_lag + 1):
                k = sums0 + lag - min_lag
                st[k] += ms_alpha * (x * st[ring0 + (pos - lag) % ring_n] - st[k])
                if st[k] > corr:
                    corr = st[k]
                    best_lag = lag
            corr /= max(st[_S_MS], 1e-12)
            st[_S_RING] = (pos + 1) % ring_n
        if st[_S_CAND] == 1.0:
            cs = int(st[_S_CAND_START])
            if x > st[_S_CAND_PEAK] and gi - cs <= max_rise:
                st[_S_CAND_PEAK] = x
                st[_S_CAND_PEAK_I] = gi
            if x <= 0.0 or gi - cs > max_rise:
                # Candidate decided: peak height, rise rate and minimum interval (seed 004 Sec. 3.2 step 3).
                h = st[_S_CAND_PEAK]
                rise = (st[_S_CAND_PEAK_I] - cs + 1) / fs
                thr = min_peak
                prev_step = st[_S_LAST] - st[_S_LAST2]
                if prev_step <= max_step and abs(cs - st[_S_LAST] - prev_step) <= beat_tol * prev_step:
                    thr = beat_peak
                gain_thr = thr
                if floor_gain > 0.0:
                    # Automatic gain: a gentle walk's own amplitude sets its floor (above the noise).
                    floor = floor_gain * math.sqrt(st[_S_MS])
                    n_pk = min(int(st[pk0]), _PEAK_RING)
                    if held_ratio > 0.0 and held[i] and steady_corr <= corr < min_corr and n_pk >= _PEAK_RING_MIN:
                        # Held phone's peak floor (module docstring): where the held-phone gate opened the gain, a
                        # crossing needs only held_ratio of the median peak of the walk's recent clear steps.
                        floor = min(floor, held_ratio * _ring_median(st[pk0 + 1:], n_pk))
                    gain_thr = min(thr, max(noise_peak, floor))
                periodic = not gated or corr >= min_corr or (steady[i] and corr >= steady_corr)
                if periodic:
                    thr = gain_thr
                rate_thr = min_rate * thr / min_peak
                gain_rate_thr = min_rate * gain_thr / min_peak
                if st[_S_AMP] > 1e-9 and peak_ratio * st[_S_AMP] > thr:
                    thr = peak_ratio * st[_S_AMP]
                if st[_S_AMP] > 1e-9 and peak_ratio * st[_S_AMP] > gain_thr:
                    gain_thr = peak_ratio * st[_S_AMP]
                spaced = cs - st[_S_LAST] >= min_interval
                accepted = h >= thr and h / rise >= rate_thr and spaced
                # A soft start: it passes the gain's floor but the walk is not (yet) periodic. Reported as such; the
                # bout that confirms right after it may take it as a first step (gait initiation).
                soft = (gated and not periodic and not accepted and spaced and h >= gain_thr
                        and h / rise >= gain_rate_thr)
                if accepted or soft:
                    starts[m] = cs
                    corrs[m] = corr
                    lags[m] = best_lag
                    peaks[m] = h
                    decided[m] = gi
                    softs[m] = soft
                    m += 1
                if accepted:
                    st[_S_LAST2] = st[_S_LAST]
                    st[_S_LAST] = cs
                    st[_S_AMP] = h if st[_S_AMP] <= 1e-9 else 0.8 * st[_S_AMP] + 0.2 * h
                    if h >= floor_gain * math.sqrt(st[_S_MS]):
                        # A clear step (above the RMS floor) sets the held phone's peak floor; the steps that only
                        # the peak floor let through do not lower it further.
                        st[pk0 + 1 + int(st[pk0]) % _PEAK_RING] = h
                        st[pk0] += 1.0
                st[_S_CAND] = 0.0
                if x > 0.0 and not accepted:
                    # Rejected on time-out while still above the reference (a noise crossing before a
                    # slow rise): the rise is measured again from here.
                    st[_S_PREV_D] = 0.0
        if st[_S_CAND] == 0.0 and x > 0.0 and st[_S_PREV_D] <= 0.0 and gi > 0:
            st[_S_CAND] = 1.0
            st[_S_CAND_START] = gi
            st[_S_CAND_PEAK] = x
            st[_S_CAND_PEAK_I] = gi
        st[_S_PREV_D] = x
    st[_S_INDEX] = base + n
    return starts[:m], peaks[:m], decided[:m], corrs[:m], softs[:m], lags[:m]


class StepDetector:
    """Online step detector over uniform-rate accelerometer batches.

    Parameters
    ----------
    rate_hz
        Grid rate of the batches (Hz).
    config
        Detector parameters.
    """

    def __init__(self, rate_hz: float, config: StepConfig | None = None) -> None:
        if not rate_hz > 0:
            raise InputError(f"rate must be positive, got {rate_hz}", field="rate_hz", source="step detector")
        self.rate_hz = float(rate_hz)
        self.config = config or StepConfig()
        c = self.config
        nyq = 0.5 * self.rate_hz
        for name in ("cutoff_hz", "gravity_hz"):
            if getattr(c, name) >= nyq:
                raise InputError(f"cut-off {getattr(c, name)} Hz must be below the Nyquist frequency {nyq} Hz",
                                 field=name, source="step config")
        self._b, self._a = iir.butter_lowpass(2, c.cutoff_hz / nyq)
        self._rb, self._ra = iir.butter_lowpass(1, c.reference_hz / nyq)
        self._gb, self._ga = iir.butter_lowpass(1, c.gravity_hz / nyq)
        self._zi: FloatArray | None = None      # (3, 2) component filter states
        self._rzi: FloatArray | None = None     # (1,) reference filter state
        self._gzi: FloatArray | None = None     # (3, 1) gravity filter states
        self._tzi: FloatArray | None = None     # (1, 3) running mean of the gravity direction (steady tilt)
        self._dzi: FloatArray | None = None     # (1,) running mean square of its deviation from that mean
        self._energy = 0.0                      # running sum of (a_n - reference)^2 over every sample seen
        self._kernel = np.zeros(_kernel_size(c, self.rate_hz))
        self._kernel[_S_LAST] = -1e12
        self._kernel[_S_LAST2] = -2e12
        self._kernel[_S_MS] = _initial_ms(c)
        # Walking bout bookkeeping: accepted starts not yet reported (_Start rows), whether the bout is
        # confirmed, the stride RMS of its recent steady steps, and its doubtful steps held back (_Held rows).
        self._bout: list[_Start] = []
        self._bout_confirmed = False
        self._reanchored = False                # the candidate is the tail of an irregular run (no short walk)
        self._steady_rms: list[float] = []
        self._held: list[_Held] = []
        self._short: list[list[tuple[int, float]]] = []   # short regular runs of (start, peak), oldest first
        self._lone: list[list[tuple[int, float]]] = []    # those of them that may be a walk alone (lone_walks)
        self._walk_end: int | None = None       # last start of the last confirmed bout or run after it (lone_walks)
        self._soft: list[_Start] = []           # recent soft starts (gait periodicity not yet established)
        # The last confirmed bout, while a short run after it may walk on: (last start, stride (samples), median peak).
        self._walked: tuple[int, float, float] | None = None
        self._n_seen = 0
        # The last start was a held walk's (the phone at a steady tilt, the signal periodic): its bout rules are
        # _held_rules.
        self._held_mode = False
        # Gravity direction (device frame, m/s^2) at the latest start of a confirmed bout: the tilt the walker
        # walks with (held walk), None before any walk.
        self._walk_up: tuple[float, float, float] | None = None
        self._walk_peak = 0.0                   # and its median peak (m/s^2)
        self._held_rules = replace(c, min_bout_steps=c.held_min_bout_steps,
                                   bout_spread=c.held_bout_spread, step_spread=c.held_step_spread)
        self._held_first_rules = replace(self._held_rules, min_bout_steps=c.min_bout_steps)
        self._held_run = 0

    @property
    def _rules(self) -> StepConfig:
        """The bout rules of the last start: the held walk's or the configured ones."""
        if not self._held_mode:
            return self.config
        return self._held_first_rules if self._walk_up is None else self._held_rules

    # -- state -------------------------------------------------------------------------------------
    @property
    def samples_seen(self) -> int:
        """Number of samples fed so far: the grid index of the next sample :meth:`update` gets."""
        return self._n_seen

    def state(self) -> dict[str, Any]:
        return {"rate_hz": self.rate_hz, "config": asdict(self.config),
                "zi": None if self._zi is None else self._zi.tolist(),
                "rzi": None if self._rzi is None else self._rzi.tolist(),
                "gzi": None if self._gzi is None else self._gzi.tolist(), "energy": self._energy,
                "tzi": None if self._tzi is None else self._tzi.tolist(),
                "dzi": None if self._dzi is None else self._dzi.tolist(),
                "kernel": self._kernel.tolist(), "bout": [list(b) for b in self._bout],
                "bout_confirmed": self._bout_confirmed, "reanchored": self._reanchored,
                "steady_rms": list(self._steady_rms),
                "held": [list(h) for h in self._held], "n_seen": self._n_seen,
                "short": [[list(r) for r in run] for run in self._short], "soft": [list(b) for b in self._soft],
                "lone": [[list(r) for r in run] for run in self._lone], "walk_end": self._walk_end,
                "walked": None if self._walked is None else list(self._walked), "held_mode": self._held_mode,
                "held_run": self._held_run,
                "walk_up": None if self._walk_up is None else list(self._walk_up), "walk_peak": self._walk_peak}

    @classmethod
    def from_state(cls, d: dict[str, Any]) -> StepDetector:
        try:
            det = cls(float(d["rate_hz"]), StepConfig(**d["config"]))
            det._zi = None if d["zi"] is None else np.array(d["zi"], dtype=np.float64)
            det._rzi = None if d["rzi"] is None else np.array(d["rzi"], dtype=np.float64)
            det._gzi = None if d["gzi"] is None else np.array(d["gzi"], dtype=np.float64)
            det._energy = float(d["energy"])
            # Absent in states saved before the held-phone gate: it starts from the next sample.
            det._tzi = None if d.get("tzi") is None else np.array(d["tzi"], dtype=np.float64)
            det._dzi = None if d.get("dzi") is None else np.array(d["dzi"], dtype=np.float64)
            kernel = np.array(d["kernel"], dtype=np.float64)
            if kernel.size == _S_LAST2:          # saved before the on-beat floor: no start before the last
                kernel = np.r_[kernel, -2e12]
            if kernel.size == _S_MS:             # saved before the automatic gain: start it as a new detector
                kernel = np.r_[kernel, _initial_ms(det.config)]
            if kernel.size == _S_SIZE:           # saved before gait periodicity: no history of it yet
                kernel = np.r_[kernel, np.zeros(_kernel_size(det.config, det.rate_hz) - _S_SIZE)]
            if kernel.size == _kernel_size(det.config, det.rate_hz) - 1 - _PEAK_RING:
                kernel = np.r_[kernel, np.zeros(1 + _PEAK_RING)]   # saved before the held peak floor: no peaks yet
            det._kernel = kernel
            det._bout = [(int(s), float(p), int(a), float(e), float(gx), float(gy), float(gz))
                         for s, p, a, e, gx, gy, gz in d["bout"]]
            det._bout_confirmed = bool(d["bout_confirmed"])
            det._reanchored = bool(d.get("reanchored", False))   # absent in states saved before re-anchoring
            det._steady_rms = [float(x) for x in d["steady_rms"]]
            det._held = [(int(s), int(e), float(p), bool(h), float(r)) for s, e, p, h, r in d["held"]]
            det._n_seen = int(d["n_seen"])
            det._held_mode = bool(d.get("held_mode", False))   # absent in states saved before held walks
            det._held_run = int(d.get("held_run", 0))          # absent in states saved before held first walks
            up = d.get("walk_up")
            det._walk_up = None if up is None else (float(up[0]), float(up[1]), float(up[2]))
            det._walk_peak = float(d.get("walk_peak", 0.0))
            # Absent in states saved before short walks were kept.
            det._short = [[(int(s), float(p)) for s, p in run] for run in d.get("short", [])]
            det._lone = [[(int(s), float(p)) for s, p in run] for run in d.get("lone", [])]   # absent before lone walks
            walk_end = d.get("walk_end")
            det._walk_end = None if walk_end is None else int(walk_end)
            walked = d.get("walked")            # absent in states saved before short walks after a bout
            det._walked = None if walked is None else (int(walked[0]), float(walked[1]), float(walked[2]))
            det._soft = [(int(s), float(p), int(a), float(e), float(gx), float(gy), float(gz))    # absent before
                         for s, p, a, e, gx, gy, gz in d.get("soft", [])]                          # gait periodicity
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"bad step detector state ({exc})", source="step detector state") from None
        return det

    # -- walking bouts -----------------------------------------------------------------------------
    def _rhythm_stride(self) -> float:
        """The open bout's stride (samples): the median over its last :data:`_STRIDE_HISTORY` starts."""
        return _median(_strides([b[0] for b in self._bout[-_STRIDE_HISTORY:]]))

    def _rhythm_peak(self) -> float:
        """The open bout's step strength (m/s^2): the median peak of its last :data:`_PEAK_HISTORY` starts."""
        return _median([b[1] for b in self._bout[-_PEAK_HISTORY:]])

    def _ends_bout(self, s: int, p: float) -> bool:
        """True if start ``s`` (peak ``p``) breaks the rhythm of the open bout (module docstring)."""
        c = self._rules
        if len(self._bout) < 3:
            return False
        ref = self._rhythm_stride()
        stride = s - self._bout[-2][0]
        off_rhythm = not c.min_stride_ratio * ref <= stride <= c.max_stride_ratio * ref
        if not self._bout_confirmed:
            return off_rhythm
        weak = p < c.weak_peak_ratio * self._rhythm_peak()
        return off_rhythm and weak

    def _rhythm_tail(self, s: int) -> int:
        """How many of the latest candidate starts walk at the rhythm of start ``s``: the longest run before
        ``s`` whose strides, with ``s``'s, agree within ``bout_spread`` (longest / shortest); 0 if none.
        """
        c = self._rules
        st = [b[0] for b in self._bout] + [s]
        n = 2                                   # the run st[-n:] (s and the start before it) has no stride yet
        lo, hi = math.inf, 0.0
        while n < len(st):
            stride = st[-n + 1] - st[-n - 1]    # the stride that taking st[-n - 1] adds
            lo, hi = min(lo, stride), max(hi, stride)
            if hi > c.bout_spread * lo:
                break
            n += 1
        return n - 1 if n >= 3 else 0

    def _max_gap(self) -> int:
        """Longest gap (samples) between two starts of the open bout: ``max_step_s``, or for a confirmed bout whose
        stride is longer than that, ``max_missed_ratio`` strides (a slow walker's missed step: a gentle hand-held
        walk of 0.9 s steps leaves a 1.6-1.8 s gap, which must not end the walk).
        """
        c = self._rules
        max_step = int(round(c.max_step_s * self.rate_hz))
        if not c.slow_missed_steps or not self._bout_confirmed or len(self._bout) < 3:
            return max_step
        stride = self._rhythm_stride()
        if c.min_missed_ratio * stride <= max_step:
            # Not a slow walker: a missed step's gap can stay within max_step_s (the plain missed-step rule); a
            # longer gap at this pace is a stop.
            return max_step
        return max(max_step, int(c.max_missed_ratio * stride))

    def _double_crossing(self, s: int) -> bool:
        """True if the open candidate bout's last start is a second crossing of one step, judged when start ``s``
        arrives: the intervals on both sides of it are shorter than a walking step (``min_bout_step_s``, about 2.6
        steps/s) and together make one step, not one stride, of the candidate's rhythm (less than
        :data:`_STEP_OF_STRIDE` times its median stride over the starts before it). The feet land once per step, so
        such a start is the same contact's second hump (a double peak); kept, it broke the candidate's rhythm and cost a
        walk its first steps. A back pocket's asymmetric steps (0.35 s / 0.65 s) have one long side and span a stride.
        """
        c = self._rules
        if not c.double_crossings or self._bout_confirmed or len(self._bout) < 4:
            return False
        before, last = self._bout[-2][0], self._bout[-1][0]
        step = c.min_bout_step_s * self.rate_hz
        if not (last - before < step and s - last < step):
            return False
        ref = _median(_strides([b[0] for b in self._bout[-_STRIDE_HISTORY - 1:-1]]))
        # The step it leaves must also agree with the same leg's step one stride before, as closely as a short walk's
        # strides (inferred evidence, like a soft first step): handling before a walk splits no regular step.
        leg = (s - before) / max(self._bout[-3][0] - self._bout[-4][0], 1)
        return s - before < _STEP_OF_STRIDE * ref and 1.0 / c.short_bout_spread <= leg <= c.short_bout_spread

    def _missed_start(self, s: int, p: float) -> int | None:
        """Start of a step missed just before start ``s`` in a confirmed bout, or None (module docstring)."""
        c = self._rules
        if not self._bout_confirmed or len(self._bout) < 3:
            return None
        last = self._bout[-1][0]
        gap = s - last
        if gap > self._max_gap():
            return None
        ref = self._rhythm_stride()
        if not c.min_missed_ratio * ref <= gap <= c.max_missed_ratio * ref:
            return None
        if gap < 2.0 * c.min_bout_step_s * self.rate_hz:
            return None                         # two steps in the gap would be faster than walking (module doc)
        if p < c.weak_peak_ratio * self._rhythm_peak():
            return None
        # The missed start follows the last one as that one followed its predecessor (the two legs
        # alternate), unless that leaves less than the minimum interval on a side: then the midpoint.
        gap_min = int(round(c.min_interval_s * self.rate_hz))
        missed = last + (self._bout[-2][0] - self._bout[-3][0])
        if not last + gap_min <= missed <= s - gap_min:
            missed = (last + s) // 2
        return missed

    def _confirmed_from(self, corr: float = 0.0, lag: int = 0) -> int | None:
        """Index in the candidate bout of its first step if the bout is now confirmed, else None.

        ``corr`` is the gait periodicity when the latest start was decided and ``lag`` (samples) the stride lag where
        it peaks: at or above ``gait_confirm_corr`` (when that is on) the signal repeats itself every stride, and
        ``gait_confirm_steps`` starts whose own stride is that lag or twice it (within ``short_bout_spread``) confirm
        the bout.
        The signal's period must be the starts' own: the window still holds the walk before a stop, and handling the
        phone after it must not confirm on that walk's periodicity.
        """
        c = self._rules
        n = len(self._bout)
        need = c.min_bout_steps
        if 0.0 < c.gait_confirm_corr <= corr and n >= max(c.gait_confirm_steps, 3):
            recent = [b[0] for b in self._bout[-c.gait_confirm_steps:]]
            own = _median(_strides(recent))
            # The period is a stride, or a step when the legs look alike (a hand-held phone).
            if own > 0 and any(1.0 / c.short_bout_spread <= k * lag / own <= c.short_bout_spread for k in (1, 2)):
                need = c.gait_confirm_steps
        if n < need:
            return None
        first = n - need
        st = np.array([b[0] for b in self._bout], dtype=np.float64)
        window = st[first:]
        if window.size < 3:
            return first
        strides = window[2:] - window[:-2]
        if strides.max() > c.bout_spread * strides.min():
            return None
        steps = np.diff(window)
        if _median(steps.tolist()) < c.min_bout_step_s * self.rate_hz:
            # Faster than walking (about 2.6 steps/s and more): the phone being handled or put away.
            return None
        same_leg = steps[:-2] / steps[2:]
        if same_leg.size and (same_leg.max() > c.step_spread or same_leg.min() < 1.0 / c.step_spread):
            return None
        ref = float(np.median(strides))
        # Take earlier starts (gait initiation) while their strides stay in the band of the bout's rhythm
        # and each step agrees with the same leg's step one stride later. Soft starts (the gain's floor passed before
        # the walk was periodic) are candidates too; one that does not fit is skipped.
        head = self._bout[first:]
        # A soft start is a first step only if as strong as the bout's steps (putting a phone away is softer).
        strong = c.short_bout_peak_ratio * _median([b[1] for b in head])
        soft = [b for b in self._soft
                if head[0][0] - 2 * c.max_step_s * self.rate_hz < b[0] < head[0][0] and b[1] >= strong]
        self._soft = []
        rest = sorted(self._bout[:first] + soft)
        while rest:
            cand = rest[-1]
            stride = (head[1][0] - cand[0]) / ref
            leg = (head[0][0] - cand[0]) / max(head[2][0] - head[1][0], 1)
            # A soft start is weaker evidence: its stride and step must agree as closely as a short walk's.
            lo, hi, spread = ((1.0 / c.short_bout_spread, c.short_bout_spread, c.short_bout_spread) if cand in soft
                              else (c.min_stride_ratio, c.max_stride_ratio, c.step_spread))
            if (lo <= stride <= hi and 1.0 / spread <= leg <= spread
                    and head[0][0] - cand[0] >= c.min_interval_s * self.rate_hz):
                head.insert(0, rest.pop())
            elif cand in soft:
                rest.pop()
            else:
                break
        self._bout = rest + head
        return len(rest)

    def _short_run(self) -> list[tuple[int, float]] | None:
        """The unconfirmed candidate bout as a short walk if its strides are regular (module docstring), else None."""
        c = self._rules
        if self._bout_confirmed or self._reanchored or len(self._bout) < c.min_short_bout_steps:
            return None
        st = np.array([b[0] for b in self._bout], dtype=np.float64)
        strides = st[2:] - st[:-2]
        if strides.max() > c.short_bout_spread * strides.min():
            return None
        return [(b[0], b[1]) for b in self._bout]

    def _weak_rms(self) -> float:
        """RMS of ``a_n - reference`` (m/s^2) below which a stride is weak: ``weak_energy_ratio`` times the median of
        the bout's recent steady strides (walk-end rule, module docstring); NaN before any (nothing is weak).
        """
        if not self._steady_rms:
            return math.nan
        return self.config.weak_energy_ratio * _median(self._steady_rms)

    def _keeps_walk_tilt(self, g: np.ndarray) -> bool:
        """True if the unit gravity direction ``g`` (device frame) lies within ``handling_angle_deg`` of its direction
        at the latest start of a confirmed walk (module docstring, held walk; True before any walk).
        """
        if self._walk_up is None:
            return True
        w = np.asarray(self._walk_up, dtype=np.float64)
        # np.linalg.norm of a float vector is the root of its dot product with itself: that, without its checks.
        n = math.sqrt(g.dot(g)) * math.sqrt(w.dot(w))
        cos = max(-1.0, min(1.0, float(g @ w) / n)) if n > 0.0 else -1.0
        return math.degrees(math.acos(cos)) <= self.config.handling_angle_deg

    def _walks_alone(self) -> bool:
        """True if the candidate bout, a regular short run (:meth:`_short_run`), may be a walk on its own
        (``lone_walks``): it starts more than ``short_bout_gap_s`` after the last confirmed bout's last start, its
        median step is a walking pace (``min_bout_step_s`` to ``max_step_s``), each step agrees with the same leg's
        step one stride later (``step_spread``), and the gravity direction in the device frame stays within
        ``handling_angle_deg`` of its direction at the first start over all its starts: walking keeps the phone's
        tilt, while getting into or out of a car, sitting down or putting the phone away turns it (a pocket phone by
        about 90 deg with the thigh).
        """
        c = self._rules
        if not c.lone_walks or len(self._bout) < c.min_lone_walk_steps:
            return False
        if self._walk_end is not None and self._bout[0][0] - self._walk_end <= c.short_bout_gap_s * self.rate_hz:
            return False                        # right after a walk: the short walks after a walk judge it
        starts = np.array([b[0] for b in self._bout], dtype=np.float64)
        steps = np.diff(starts)
        if not c.min_bout_step_s * self.rate_hz <= _median(steps.tolist()) <= c.max_step_s * self.rate_hz:
            return False
        same_leg = steps[:-2] / steps[2:]
        if same_leg.size and (same_leg.max() > c.step_spread or same_leg.min() < 1.0 / c.step_spread):
            return False
        g = np.array([b[4:7] for b in self._bout], dtype=np.float64)
        cos = np.clip(g @ g[0], -1.0, 1.0)
        return bool(np.degrees(np.arccos(cos.min())) <= c.handling_angle_deg)

    def _walks_on(self, run: list[tuple[int, float]], pause: int, ref: float, peak: float) -> bool:
        """True if the regular run ``run`` of (start, peak) walks on with a bout of stride ``ref`` (samples) and median
        peak ``peak`` (m/s^2) across a pause of ``pause`` samples between them: the pause is at least one step
        (``min_stride_ratio`` times half the stride) and at most ``short_bout_gap_s``, the run's median stride is within
        ``[min_stride_ratio, max_stride_ratio]`` times ``ref`` and its median peak at least ``short_bout_peak_ratio``
        times ``peak``.
        """
        c = self._rules
        stride = _median(_strides([r[0] for r in run]))
        pause_ok = 0.5 * c.min_stride_ratio * ref <= pause <= c.short_bout_gap_s * self.rate_hz
        rhythm_ok = c.min_stride_ratio * ref <= stride <= c.max_stride_ratio * ref
        return pause_ok and rhythm_ok and _median([r[1] for r in run]) >= c.short_bout_peak_ratio * peak

    def _run_steps(self, run: list[tuple[int, float]]) -> list[tuple[int, int, float]]:
        """Steps (start, end, peak) of a regular run: each ends where the next starts, the last after the run's median
        step (at most ``max_step_s``).
        """
        starts = [r[0] for r in run]
        dur = min(int(np.median(np.diff(starts))), int(round(self._rules.max_step_s * self.rate_hz)))
        ends = starts[1:] + [starts[-1] + dur]
        return [(s0, e0, p0) for (s0, p0), e0 in zip(run, ends, strict=True)]

    def _claim_short(self, first_start: int, ref: float, peak: float) -> list[tuple[int, int, float]]:
        """Steps (start, end, peak) of the short walks just before a bout confirmed at ``first_start``.

        Runs are taken newest first while each walks on with the bout (:meth:`_walks_on`: ``ref`` is the bout's
        stride, ``peak`` its median peak) across the pause to the start after it.
        """
        taken: list[list[tuple[int, float]]] = []
        nxt = first_start
        for run in reversed(self._short):
            if not self._walks_on(run, nxt - run[-1][0], ref, peak):
                break
            taken.append(run)
            nxt = run[0][0]
        self._short = []
        self._lone = []
        return [step for run in reversed(taken) for step in self._run_steps(run)]

    def _claim_after(self, run: list[tuple[int, float]]) -> list[tuple[int, int, float]]:
        """Steps of the short regular ``run`` if it walks on after the last confirmed bout (:meth:`_walks_on` across
        the pause from that bout's last start), else none. A claimed run becomes the walk's end for the next one.
        """
        if self._walked is None:
            return []
        last, ref, peak = self._walked
        if not self._walks_on(run, run[0][0] - last, ref, peak):
            return []
        self._walked = (run[-1][0], ref, peak)
        self._walk_end = run[-1][0]
        return self._run_steps(run)

    def _stride(self, i: int) -> tuple[float, float]:
        """RMS of ``a_n - reference`` (m/s^2) and gravity turn (deg) over the stride around step ``bout[i]``.

        The stride runs from the decision of the previous start (of this start for the bout's first step) to
        the decision of the next one, so it is known when step ``i`` is reported. RMS is NaN if it is empty.
        """
        a, b = self._bout[max(i - 1, 0)], self._bout[i + 1]
        n = b[2] - a[2]
        rms = math.sqrt(max(b[3] - a[3], 0.0) / n) if n > 0 else math.nan
        cos = a[4] * b[4] + a[5] * b[5] + a[6] * b[6]
        return rms, math.degrees(math.acos(min(max(cos, -1.0), 1.0)))

    # -- processing --------------------------------------------------------------------------------
    def filtered_norm(self, acc_b: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Low-passed norm ``a_n`` (eq. 12) and reference level for a batch; advances the filter states."""
        acc = np.asarray(acc_b, dtype=np.float64)
        if self._zi is None:
            zi0 = iir.lfilter_zi(self._b, self._a)
            self._zi = np.outer(acc[0], zi0)
        af = np.empty_like(acc)
        for i in range(3):
            af[:, i], self._zi[i] = iir.lfilter(self._b, self._a, acc[:, i], self._zi[i])
        an = np.sqrt(np.sum(af * af, axis=1))
        if self._rzi is None:
            self._rzi = iir.lfilter_zi(self._rb, self._ra) * an[0]
        ref, self._rzi = iir.lfilter(self._rb, self._ra, an, self._rzi)
        return an, ref

    def _gravity_dir(self, acc: FloatArray) -> FloatArray:
        """(N, 3) unit gravity direction in the device frame (slow low-pass of the components)."""
        if self._gzi is None:
            self._gzi = np.outer(acc[0], iir.lfilter_zi(self._gb, self._ga))
        g = np.empty_like(acc)
        for i in range(3):
            g[:, i], self._gzi[i] = iir.lfilter(self._gb, self._ga, acc[:, i], self._gzi[i])
        return g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-9)

    def _steady(self, grav: FloatArray) -> NDArray[np.bool_]:
        """(N,) True where the phone is held at a steady tilt: the RMS angle (deg) of the unit gravity direction
        ``grav`` (N, 3, device frame) about its running mean, both exponential windows of ``floor_tau_s``, is at most
        ``steady_tilt_deg`` (small angles: the chord is the angle in rad), starting unsteady. All False when the rule is
        off.
        """
        c = self.config
        if not c.steady_tilt_deg > 0:
            return np.zeros(grav.shape[0], dtype=bool)
        alpha = 1.0 / (c.floor_tau_s * self.rate_hz)
        b, a = np.array([alpha]), np.array([1.0, alpha - 1.0])
        if self._tzi is None or self._dzi is None:
            # A detector that has seen nothing yet does not take the phone for steady: the deviation starts at twice
            # the limit and needs about floor_tau_s * ln 4 of steady holding to come under it.
            self._tzi = np.outer(iir.lfilter_zi(b, a), grav[0])
            self._dzi = iir.lfilter_zi(b, a) * math.radians(2.0 * c.steady_tilt_deg) ** 2
        m, self._tzi = iir.lfilter(b, a, grav, self._tzi)
        dev, self._dzi = iir.lfilter(b, a, np.sum((grav - m) ** 2, axis=1), self._dzi)
        return np.degrees(np.sqrt(np.maximum(dev, 0.0))) <= c.steady_tilt_deg

    def update(self, acc_b: FloatArray, final: bool = False) -> tuple[Steps, FloatArray]:
        """Feed the next batch of uniform samples.

        Parameters
        ----------
        acc_b
            (N, 3) specific force in m/s^2, body frame, at ``rate_hz`` continuing the previous batch.
        final
            True for the last batch: close the open walking bout.

        Returns
        -------
        steps
            The steps that became known in this batch (indices on the detector's global grid).
        a_n
            (N,) low-passed acceleration norm of the batch (m/s^2), for step-length patterns.
        """
        acc = np.asarray(acc_b, dtype=np.float64)
        if acc.ndim != 2 or acc.shape[1] != 3:
            raise InputError(f"acc must be (N, 3), got {acc.shape}", source="step detector")
        c = self.config
        fs = self.rate_hz
        n0 = self._n_seen
        an = np.zeros(0)
        starts = np.zeros(0, dtype=np.int64)
        peaks = np.zeros(0)
        corrs = np.zeros(0)
        softs = np.zeros(0, dtype=bool)
        lags = np.zeros(0, dtype=np.int64)
        decided = np.zeros(0, dtype=np.int64)
        energy = np.zeros(0)
        grav = np.zeros((0, 3))
        in_front = np.zeros(0, dtype=bool)
        if acc.shape[0]:
            an, ref = self.filtered_norm(acc)
            d = an - ref
            grav = self._gravity_dir(acc)
            steady = self._steady(grav)
            # Held in front (held walk, held_peak_floor): at a steady tilt, the long axis (y) more than
            # held_min_axis_tilt_deg from the vertical (grav is a unit vector).
            in_front = steady & (np.abs(grav[:, 1]) < math.cos(math.radians(c.held_min_axis_tilt_deg)))
            starts, peaks, decided, corrs, softs, lags = _detect_kernel(
                d, self._kernel, fs, c.min_peak, c.peak_ratio, c.min_rise_rate,
                int(round(c.max_rise_s * fs)), int(round(c.min_interval_s * fs)), c.amplitude_tau_s,
                c.beat_min_peak, c.beat_tolerance, int(round(c.max_step_s * fs)), c.floor_gain, c.floor_tau_s,
                c.noise_peak, c.gait_min_corr > 0.0 or c.gait_confirm_corr > 0.0, c.gait_min_corr, *_gait_lags(c, fs),
                steady, c.steady_min_corr, in_front, c.peak_ratio if c.held_peak_floor else 0.0)
            energy = self._energy + np.cumsum(d * d)
            self._energy = float(energy[-1])
        self._n_seen = n0 + acc.shape[0]
        max_step = int(round(c.max_step_s * fs))
        out_s: list[int] = []
        out_e: list[int] = []
        out_c: list[int] = []
        out_p: list[float] = []

        def report(s0: int, e0: int, p0: float, at: int, doubtful: bool = False, turned: bool = False,
                   rms: float = math.nan) -> None:
            # A doubtful step waits; the next steady step of the bout reports it (walk-end rule, module
            # docstring), a bout end drops the waiting ones if the phone turned among them.
            if doubtful:
                self._held.append((s0, e0, p0, turned, rms))
                recent = self._held[-c.soft_walk_steps:]
                if len(recent) < c.soft_walk_steps:
                    return
                if any(h[3] for h in recent):
                    # Turned steps that keep coming and, as a run, are not weak: the walk goes on (handling after a
                    # walk is weak, the walker has stopped pushing off). They are reported.
                    if not _median([h[4] if math.isfinite(h[4]) else 0.0 for h in recent]) >= self._weak_rms():
                        return
                else:
                    # Soft steps that keep coming without the phone turning: a walk in a softer carriage (the
                    # phone moved from a pocket to the hand). They are reported and set the new strength.
                    self._steady_rms = [h[4] for h in recent if math.isfinite(h[4])]
                s0, e0, p0 = self._held.pop()[:3]
            for hs, he, hp, *_ in self._held:
                out_s.append(hs)
                out_e.append(he)
                out_c.append(at)
                out_p.append(hp)
            self._held = []
            out_s.append(s0)
            out_e.append(e0)
            out_c.append(at)
            out_p.append(p0)

        def close_bout(at: int) -> None:
            # The bout's last step ends at its start plus the bout's median step duration (<= max_step).
            run = self._short_run()
            tail = self._claim_after(run) if run is not None else []
            for s0, e0, p0 in tail:
                # A short walk right after a confirmed bout, at its rhythm and strength: the walk went on after a
                # missed step or a brief stop (the mirror of the short walks claimed by a bout after them).
                report(s0, e0, p0, at)
            if run is not None and not tail:
                self._short = (self._short + [run])[-_SHORT_HISTORY:]
                if self._walks_alone():
                    self._lone = (self._lone + [run])[-_SHORT_HISTORY:]
            if self._bout_confirmed and self._bout:
                self._walk_end = self._bout[-1][0]
            if not self._bout_confirmed and not tail and self._bout:
                self._walked = None             # starts between a walk and a later run: the walk does not go on
            if self._bout_confirmed and self._bout:
                # The walk may go on after a pause (a missed soft step, a brief stop): kept for the next short run,
                # unless it ended in handling (the phone turned among its held steps).
                ended_in_handling = any(h[3] for h in self._held)
                self._walked = None if ended_in_handling or len(self._bout) < 3 else (
                    self._bout[-1][0], self._rhythm_stride(), self._rhythm_peak())
                s, p = self._bout[-1][0], self._bout[-1][1]
                durs = np.diff([b[0] for b in self._bout]) if len(self._bout) > 1 else np.zeros(0)
                dur = int(np.median(durs)) if durs.size else max_step
                if any(h[3] for h in self._held):
                    # The walk ended in handling: its first soft step is the walk's last (the feet come
                    # together); the other held steps and this last start are the phone being handled.
                    first = self._held[:1]
                    self._held = []
                    for hs, he, hp, *_ in first:
                        report(hs, he, hp, at)
                else:
                    report(s, s + min(dur, max_step), p, at)
            self._bout = []
            self._bout_confirmed = False
            self._reanchored = False
            self._steady_rms = []
            self._held = []

        def emit(lo: int, at: int) -> None:
            # Steps bout[lo:-1], each ending where the next one starts, reported at sample `at` (or held).
            if not self._steady_rms:
                seed = [self._stride(i)[0] for i in range(lo, len(self._bout) - 1)]
                self._steady_rms = [x for x in seed if math.isfinite(x)]
            for i in range(lo, len(self._bout) - 1):
                rms, turn = self._stride(i)
                weak = rms < self._weak_rms()
                turned = turn > c.handling_angle_deg
                if math.isfinite(rms) and not (weak or turned):
                    self._steady_rms = (self._steady_rms + [rms])[-_PEAK_HISTORY:]
                report(self._bout[i][0], self._bout[i + 1][0], self._bout[i][1], at,
                       weak or (turned and bool(self._held)), turned, rms)

        for s, p, at, corr, soft, lag in zip(starts.tolist(), peaks.tolist(), decided.tolist(), corrs.tolist(),
                                             softs.tolist(), lags.tolist(), strict=True):
            k = at - n0
            # Held walk (module docstring): this start's bout rules are the held phone's while it holds its tilt and
            # the signal repeats at a stride.
            held = bool(c.held_walks and in_front[k] and corr >= c.steady_min_corr
                        and self._keeps_walk_tilt(grav[k])
                        and p >= c.short_bout_peak_ratio * self._walk_peak)
            if not soft:                        # consecutive held starts (a soft start is not in the bout)
                self._held_run = self._held_run + 1 if held else 0
            # Before the first walk, the held rules judge only a candidate all of whose starts were held ones.
            self._held_mode = held and (self._walk_up is not None or self._held_run > len(self._bout))
            max_step = int(round(self._rules.max_step_s * fs))
            row: _Start = (s, p, at, float(energy[k]), float(grav[k, 0]), float(grav[k, 1]), float(grav[k, 2]))
            if soft:
                # Kept a while: the bout that confirms next may take it as its first step (gait initiation).
                self._soft = (self._soft + [row])[-_SOFT_HISTORY:]
                continue
            if self._double_crossing(s):
                # The last start split one step in two (module docstring): the feet land once per step.
                self._bout.pop()
            missed = self._missed_start(s, p)
            if missed is not None:
                # One step of the bout was not detected: infer it from the rhythm (module docstring). Its
                # stride figures are those of the start after it.
                self._bout.append((missed, 0.5 * (self._bout[-1][1] + p),) + row[2:])
                emit(len(self._bout) - 2, at)
            if self._bout and s - self._bout[-1][0] > max_step:
                close_bout(min(self._bout[-1][0] + self._max_gap() + 1, at))
            elif self._ends_bout(s, p):
                # An unconfirmed candidate keeps its latest starts that walk at the rhythm of the new one
                # (a walk starting right after handling); the older ones close as before.
                keep = [] if self._bout_confirmed else self._bout[len(self._bout) - self._rhythm_tail(s):]
                if keep:
                    self._bout = self._bout[:-len(keep)]
                close_bout(at)
                self._bout = keep
                self._reanchored = bool(keep)
            self._bout.append(row)
            if self._bout_confirmed:
                self._walk_up, self._walk_peak = (row[4], row[5], row[6]), self._rhythm_peak()
                emit(len(self._bout) - 2, at)
                self._bout = self._bout[-_BOUT_HISTORY:]
                continue
            first = self._confirmed_from(corr, lag)
            if first is not None:
                self._bout_confirmed = True
                self._walk_up, self._walk_peak = (row[4], row[5], row[6]), self._rhythm_peak()
                if self._short:
                    # Short walks just before this bout (between two stops at a landmark) are steps too.
                    window = np.array([b[0] for b in self._bout[-self._rules.min_bout_steps:]], dtype=np.float64)
                    stride_ref = float(np.median(window[2:] - window[:-2])) if window.size >= 3 else 0.0
                    bout_peak = float(np.median([b[1] for b in self._bout[first:]]))
                    for s0, e0, p0 in self._claim_short(self._bout[first][0], stride_ref, bout_peak):
                        report(s0, e0, p0, at)
                emit(first, at)
                self._bout = self._bout[-_BOUT_HISTORY:]
            else:
                self._bout = self._bout[-_CANDIDATE_HISTORY:]
        # The bout is over when no start can come within max_step of its last one; a crossing still being
        # decided by the kernel may (as in one batch, where it would arrive before the bout is closed).
        gap = self._max_gap() if self._bout else max_step
        pending = bool(self._bout) and self._kernel[_S_CAND] == 1.0 and (
            self._kernel[_S_CAND_START] - self._bout[-1][0] <= gap)
        if self._bout and ((self._n_seen - 1 - self._bout[-1][0] > gap and not pending) or final):
            close_bout(min(self._bout[-1][0] + gap + 1, self._n_seen))
        if final and self._lone:
            # Short walks that no walk came before or after: the recording holds only them (lone_walks). They come
            # after every reported step (a bout confirming after them clears them), so the steps stay in order.
            for run in self._lone:
                for s0, e0, p0 in self._run_steps(run):
                    report(s0, e0, p0, self._n_seen)
            self._lone = []
            self._short = []
        steps = Steps(np.array(out_s, dtype=np.int64), np.array(out_e, dtype=np.int64),
                      np.array(out_c, dtype=np.int64), np.array(out_p, dtype=np.float64))
        return steps, an


def detect_steps(acc_b: FloatArray, rate_hz: float, config: StepConfig | None = None) -> Steps:
    """Steps of a whole uniform-rate recording (one batch through :class:`StepDetector`)."""
    steps, _ = StepDetector(rate_hz, config).update(acc_b, final=True)
    return steps
