# table1-followup-particle-std: redraw with `gnuplot /work/main/docs/results/table1/table1-followup-particle-std.curves.svg.gp`
set terminal svg size 760,480 dynamic font "sans,11"
set output "/work/main/docs/results/table1/table1-followup-particle-std.curves.svg"
set termoption noenhanced
set style fill transparent solid 0.18 noborder
set grid
set xlabel "episode"
set ylabel "evaluation cost"
set xtics 1
set key outside right top vertical box font ",9" samplen 2 spacing 0.9
set multiplot layout 1,1 title "sweep table1-followup-particle-std: evaluation cost per episode, median and quartiles over trials (n = trials)"
set title "cartpole-swingup, tip cost, k = 1, normalisation=particle_std"
plot "/work/main/docs/results/table1/table1-followup-particle-std.curves.svg.dat" index 0 using 1:2:4 with filledcurves lc rgb "#e15759" notitle, \
     "/work/main/docs/results/table1/table1-followup-particle-std.curves.svg.dat" index 0 using 1:3 with linespoints lc rgb "#e15759" lw 2 pt 7 ps 0.5 title "RP (n=4)", \
     "/work/main/docs/results/table1/table1-followup-particle-std.curves.svg.dat" index 1 using 1:2:4 with filledcurves lc rgb "#59a14f" notitle, \
     "/work/main/docs/results/table1/table1-followup-particle-std.curves.svg.dat" index 1 using 1:3 with linespoints lc rgb "#59a14f" lw 2 pt 7 ps 0.5 title "GTP (n=4)", \
     15 with lines dt 2 lw 1.5 lc rgb "#555555" title "success threshold 15"
unset multiplot
