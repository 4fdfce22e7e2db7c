# Sourced by benches/instructions.sh and benches/hot_instructions.sh (not run on its own): what
# both need to count a scene's instructions under valgrind. benches/detection_bound.sh uses its
# scene_for_steps too.

# glibc clears and copies large blocks with `rep stosb` and `rep movsb`, which valgrind counts once
# per byte: the forces' and torques' zeroing alone read as 33 "instructions" per particle-step,
# 7 % of the table, where the vector loop that replaces it takes about 2.5. The tunables move
# the threshold for those string instructions out of reach for the measured run only (as
# GLIBC_TUNABLES=$REP_OFF), so memset counts instructions like every other function (the timed
# runs keep glibc's choice).
REP_OFF=glibc.cpu.x86_rep_stosb_threshold=1000000000000:glibc.cpu.x86_rep_movsb_threshold=1000000000000

# scene_for_steps SCENE STEPS OUT: writes to OUT a copy of SCENE that runs STEPS steps of its dt,
# its data files found in SCENE's own folder wherever OUT is run.
scene_for_steps() {
  local scene=$1 steps=$2 out=$3 scene_dir dt duration
  scene_dir=$(realpath "$(dirname "$scene")")
  dt=$(sed -n 's/^dt_s *= *\([0-9.eE+-]*\).*/\1/p' "$scene" | head -1)
  [ -n "$dt" ] || { echo "$scene: no simulation.dt_s found" >&2; return 1; }
  duration=$(python3 -c "print($steps * $dt)")
  sed -e "s|file = \"data/|file = \"$scene_dir/data/|" \
      -e "s|^duration_s *=.*|duration_s = $duration|" "$scene" > "$out"
}

# particles_of RUN_OUTPUT: the particle count am-sim's header line names.
particles_of() {
  local particles
  particles=$(sed -n 's/.* — \([0-9]*\) particles,.*/\1/p' "$1" | head -1)
  [ -n "$particles" ] || { echo "could not read the particle count from am-sim's header in $1" >&2; return 1; }
  echo "$particles"
}
