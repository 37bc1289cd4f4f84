function o = optimoptions(solver, varargin)
  % Octave 7 has no optimoptions(); pwcmp's pw_scale.m calls
  % optimoptions('fminunc', 'SpecifyObjectiveGradient', USE_GRADIENTS, 'Display', 'off').
  % This stand-in (studyapp's, not pwcmp's) returns the equivalent optimset, with the
  % tolerances tightened so that the scores are the optimum rather than a nearby point.
  grad = 'on';
  for kk = 1:2:numel(varargin)
    if strcmp(varargin{kk}, 'SpecifyObjectiveGradient') && ~varargin{kk + 1}
      grad = 'off';
    end
  end
  o = optimset('GradObj', grad, 'TolFun', 1e-30, 'TolX', 1e-30, ...
               'MaxIter', 10000, 'MaxFunEvals', 100000, 'Display', 'off');
end
