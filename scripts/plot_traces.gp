# PNG plots of the closed-loop traces (CSV from the closed_loop program):
#   gnuplot -e "outdir='out'" scripts/plot_traces.gp
if (!exists("outdir")) outdir = 'out'
set datafile separator ','
set terminal pngcairo size 1200,800 noenhanced font ',10'
set grid
set key top right

# Pulse (Figs. 11-12): velocities and force.
set output outdir.'/pulse.png'
set multiplot layout 2,1 title 'pulse 0.2 m/s, 1 Hz: PI only'
set ylabel 'velocity [m/s]'
plot outdir.'/pulse.csv' using 2:4 with lines lw 2 title 'V_ref', \
     '' using 2:10 with lines title 'load v_L (true)', \
     '' using 2:14 with lines dt 2 title 'load v_L (Kalman)', \
     '' using 2:8 with lines title 'motor v_M'
set xlabel 'time [s]'
set ylabel 'force [N]'
plot outdir.'/pulse.csv' using 2:17 with lines title 'force command', \
     '' using 2:12 with lines title 'spring force F_s (true)', \
     '' using 2:15 with lines dt 2 title 'F_s (Kalman)'
unset multiplot

# Free vibration (Fig. 10): phase plane of the load and the stretch over time.
set output outdir.'/free_vibration.png'
set multiplot layout 1,2 title 'free vibration from 0.02 m: PI only'
set xlabel 'load displacement x_L - x_M [m]'
set ylabel 'load velocity [m/s]'
plot outdir.'/free_vibration.csv' using ($9-$7):10 with lines title 'phase plane'
set xlabel 'time [s]'
set ylabel 'x_L - x_M [m]'
plot outdir.'/free_vibration.csv' using 2:($9-$7) with lines title 'spring stretch'
unset multiplot
