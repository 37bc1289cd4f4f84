% pwcmp's pw_scale (default options: 'prior' 'gaussian', 'regularization' 'mean0') on seven
% 6-condition comparison matrices with 1 to 7 unanimous pairs; prints the JOD scores.
% The constants PWCMP_UNANIMOUS_JOD in tests/test_analysis_pwcmp.py were printed by this script.
%
% Run (Debian: apt-get install octave octave-statistics; pwcmp from github.com/mantiuk/pwcmp,
% commit 07876b296a22b8e5fc25bef320f8cb26dc752b11, pw_scale.m as of 1cdd483):
%   PWCMP=/path/to/pwcmp octave --no-gui -q tests/reference/pwcmp_unanimous.m
% D(i, j) = times condition i was chosen over condition j (pwcmp's convention).
pkg load statistics
here = fileparts(mfilename('fullpath'));
addpath(fullfile(here, 'octave_shim'));
addpath(getenv('PWCMP'));
D = {};
D{1} = [0 1 3 1 1 0; 7 0 2 1 1 1; 5 6 0 2 1 1; 7 7 6 0 1 1; 7 7 7 7 0 3; 8 7 7 7 5 0];
D{2} = [0 5 3 1 1 0; 3 0 3 2 1 0; 5 5 0 1 1 1; 7 6 7 0 3 2; 7 7 7 5 0 4; 8 8 7 6 4 0];
D{3} = [0 5 1 1 0 0; 3 0 1 2 1 0; 7 7 0 1 1 1; 7 6 7 0 3 1; 8 7 7 5 0 1; 8 8 7 7 7 0];
D{4} = [0 3 2 1 0 0; 5 0 3 2 1 0; 6 5 0 3 1 0; 7 6 5 0 2 1; 8 7 7 6 0 3; 8 8 8 7 5 0];
D{5} = [0 5 1 1 0 0; 3 0 1 3 0 0; 7 7 0 3 1 0; 7 5 5 0 3 2; 8 8 7 5 0 4; 8 8 8 6 4 0];
D{6} = [0 5 2 2 0 0; 3 0 4 1 0 0; 6 4 0 2 1 0; 6 7 6 0 2 0; 8 8 7 6 0 2; 8 8 8 8 6 0];
D{7} = [0 4 3 0 0 0; 4 0 3 1 0 0; 5 5 0 1 1 0; 8 7 7 0 4 0; 8 8 7 4 0 2; 8 8 8 8 6 0];
printf('PWCMP_UNANIMOUS_JOD = [\n');
for c = 1:numel(D)
  Q = pw_scale(D{c});
  Q = Q - Q(1);  % differences to condition 1 (pwcmp centres the mean at 0)
  printf('    [%s],\n', strjoin(arrayfun(@(v) sprintf('%.12g', v), Q', 'UniformOutput', false), ', '));
end
printf(']\n');
