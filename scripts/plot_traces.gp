# PNG plots of the comparison runs, like the paper's figures. Inputs (CSV, in outdir):
#   <scenario>_pi.csv, <scenario>_pi_accel.csv, <scenario>_pi_rnn.csv, <scenario>_pi_state.csv
#   (evaluator or closed_loop)
#   history: the de_trainer's per-generation CSV (default configs/rnn_weights.history.csv)
#   gnuplot -e "outdir='out'; history='out/rnn_weights.yaml.history.csv'" scripts/plot_traces.gp
# Trace columns: 2 time_s, 4 v_ref, 7 x_M, 8 v_M, 9 x_L, 10 v_L, 14 v_L (Kalman), 17 force, 18 compensation.
if (!exists("outdir")) outdir = 'out'
set datafile separator ','
set terminal pngcairo size 1200,800 noenhanced font ',10'
set grid
set key top right

# Figs. 11-12: load velocity under the 0.2 m/s, 1 Hz pulse, with and without compensation.
set output outdir.'/pulse.png'
set multiplot layout 2,1 title 'pulse 0.2 m/s, 1 Hz (Figs. 11-12): load velocity and motor force'
set ylabel 'velocity [m/s]'
plot outdir.'/pulse_pi.csv' using 2:4 with lines lw 2 lc rgb 'black' title 'V_ref', \
     '' using 2:10 with lines lc rgb '#d62728' title 'v_L, PI only', \
     outdir.'/pulse_pi_accel.csv' using 2:10 with lines lc rgb '#1f77b4' title 'v_L, PI + acceleration feedback', \
     outdir.'/pulse_pi_rnn.csv' using 2:10 with lines lw 2 lc rgb '#2ca02c' title 'v_L, PI + RNN', \
     outdir.'/pulse_pi_state.csv' using 2:10 with lines lw 2 lc rgb '#ff7f0e' title 'v_L, PI + state feedback'
set xlabel 'time [s]'
set ylabel 'force [N]'
plot outdir.'/pulse_pi.csv' using 2:17 with lines lc rgb '#d62728' title 'force, PI only', \
     outdir.'/pulse_pi_accel.csv' using 2:17 with lines lc rgb '#1f77b4' title 'force, PI + acceleration feedback', \
     outdir.'/pulse_pi_rnn.csv' using 2:17 with lines lc rgb '#2ca02c' title 'force, PI + RNN', \
     '' using 2:18 with lines dt 2 lc rgb '#2ca02c' title 'RNN part G_n u_n', \
     outdir.'/pulse_pi_state.csv' using 2:17 with lines lc rgb '#ff7f0e' title 'force, PI + state feedback'
unset multiplot

# Fig. 10: free vibration from 0.02 m, phase plane of the load, and the stretch over time.
set output outdir.'/free_vibration.png'
set multiplot layout 1,2 title 'free vibration from 0.02 m (Fig. 10)'
unset xlabel
set xlabel 'spring stretch x_L - x_M [m]'
set ylabel 'load velocity v_L [m/s]'
plot outdir.'/free_vibration_pi.csv' using ($9-$7):10 with lines lc rgb '#d62728' title 'PI only', \
     outdir.'/free_vibration_pi_accel.csv' using ($9-$7):10 with lines lc rgb '#1f77b4' title 'PI + acceleration feedback', \
     outdir.'/free_vibration_pi_rnn.csv' using ($9-$7):10 with lines lw 2 lc rgb '#2ca02c' title 'PI + RNN', \
     outdir.'/free_vibration_pi_state.csv' using ($9-$7):10 with lines lc rgb '#ff7f0e' title 'PI + state feedback'
set xlabel 'time [s]'
set ylabel 'x_L - x_M [m]'
set xrange [0:2]
plot outdir.'/free_vibration_pi.csv' using 2:($9-$7) with lines lc rgb '#d62728' title 'PI only', \
     outdir.'/free_vibration_pi_accel.csv' using 2:($9-$7) with lines lc rgb '#1f77b4' title 'PI + acceleration feedback', \
     outdir.'/free_vibration_pi_rnn.csv' using 2:($9-$7) with lines lw 2 lc rgb '#2ca02c' title 'PI + RNN', \
     outdir.'/free_vibration_pi_state.csv' using 2:($9-$7) with lines lc rgb '#ff7f0e' title 'PI + state feedback'
unset xrange
unset multiplot

# Figs. 6-7: the weight search, best and mean cost (23) and one weight against evaluations.
if (!exists("history")) history = 'configs/rnn_weights.history.csv'
if (system('test -s '.history.' && echo yes') eq "yes") {
  set output outdir.'/training.png'
  set multiplot layout 2,1 title 'weight search (Figs. 6-7)'
  set xlabel 'evaluations'
  set ylabel 'cost (23)'
  set logscale y
  plot history using 2:3 with lines lw 2 title 'best', '' using 2:4 with lines title 'population mean'
  unset logscale y
  set ylabel 'weight 0 of the best member'
  plot history using 2:6 with lines title 'w_0'
  unset multiplot
}
